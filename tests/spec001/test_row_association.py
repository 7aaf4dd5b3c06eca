"""skytrack.analysis.row_association: rows follow their track's object across one-instant swaps."""

import numpy as np

from skytrack.analysis.row_association import smooth_along_tracks


def test_a_one_instant_swap_and_a_row_outside_the_gate_follow_the_track():
    track = np.repeat([1, 2], 7)
    time = np.tile(np.arange(7.0), 2)
    target = np.array([0, 0, 0, 1, 0, 0, 0,   # track 1 swapped to object 1 at t = 3
                       1, 1, 1, 0, -1, 1, 1])  # track 2 swapped at t = 3 and outside the gate at t = 4
    smoothed = smooth_along_tracks(target, track, time)
    np.testing.assert_array_equal(smoothed, [0] * 7 + [1] * 7)


def test_a_false_track_stays_without_object_and_a_handover_is_kept():
    track = np.repeat([5, 6], 8)
    time = np.tile(np.arange(8.0), 2)
    target = np.array([-1] * 8 + [2, 2, 2, 2, 3, 3, 3, 3])  # track 6 hands over from object 2 to 3
    smoothed = smooth_along_tracks(target, track, time)
    np.testing.assert_array_equal(smoothed[:8], -1)
    assert smoothed[8:11].tolist() == [2, 2, 2] and smoothed[13:].tolist() == [3, 3, 3]
    # rows given in any order give the same answer
    shuffle = np.random.default_rng(0).permutation(16)
    np.testing.assert_array_equal(smooth_along_tracks(target[shuffle], track[shuffle], time[shuffle]),
                                  smoothed[shuffle])


def test_last_followed_carries_each_tracks_object_forward():
    from skytrack.analysis.row_association import last_followed

    track = np.array([1, 1, 1, 1, 2, 2, 2])
    time = np.array([0.0, 1, 2, 3, 0, 1, 2])
    target = np.array([-1, 4, -1, -1, -1, -1, 7])
    np.testing.assert_array_equal(last_followed(target, track, time), [-1, 4, 4, 4, -1, -1, 7])

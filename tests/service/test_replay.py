"""skytrack replay (skytrack.service.replay, skytrack.io.asterix.recording.encode_recording): bytes equal to the libasterix
encoder's, datagram sizes, pacing, loops with rewritten times, the send log."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest

from skytrack.io.asterix import decode_asterix, encode_asterix
from skytrack.io.asterix.recording import encode_recording
from skytrack.service.pipeline import sensor_sac_sic
from skytrack.service.replay import (
    Replayer, datagram_plan, load_recording, loop_shift, read_send_log, scan_blocks, shift_times,
)


def test_numpy_encoder_writes_the_libasterix_bytes(small_scene):
    sensors, plots = small_scene
    head = plots.iloc[:300].sample(frac=1.0, random_state=3)  # unsorted input: both sort by time
    mapping = {"radar1": (12, 34)}
    for per_block in (1, 7, 128):
        expected = encode_asterix(head, mapping, time_of_day_at_epoch_s=43200.0, max_records_per_block=per_block)
        data = encode_recording(head, mapping, time_of_day_at_epoch_s=43200.0, max_records_per_block=per_block)
        assert data == expected
        starts = scan_blocks(np.frombuffer(data, np.uint8)).block_starts
        assert len(starts) == -(-300 // per_block) and data[starts[-1]] == 48
    # the plots carry Mode 3/A, Mode C and Mode S on some rows: all three optional items were exercised
    assert head["mode_s"].notna().any() and head["mode3a"].isna().any() and head["mode_c_ft"].notna().any()
    with pytest.raises(ValueError, match="no SAC/SIC for sensor"):
        encode_recording(head, {"other": (1, 1)})


def test_blocks_datagrams_and_loop_times(small_scene):
    sensors, plots = small_scene
    data = encode_recording(plots, sensor_sac_sic(sensors), max_records_per_block=20)
    recording = scan_blocks(np.frombuffer(data, np.uint8))
    assert recording.records == len(plots)
    # a block's time is its newest record's: the span runs from the first block's (the 20th plot) to the last plot
    times = np.sort(plots["time"].to_numpy())
    assert recording.span_s == pytest.approx(times[-1] - times[19], abs=2 / 128)
    bounds, oversize = datagram_plan(recording, 1400)
    ends = np.append(recording.block_starts[1:], len(data))
    sizes = [ends[bounds[k + 1] - 1] - recording.block_starts[bounds[k]] for k in range(len(bounds) - 1)]
    assert max(sizes) <= 1400 and int(oversize) == 0 and bounds[-1] == len(recording.block_starts)
    assert sum(sizes) == len(data)
    # a loop pass: every time of day later by the shift (a whole number of 4 s scans past the span)
    shift = loop_shift(recording.span_s, 4.0)
    assert shift % 4.0 == 0 and recording.span_s < shift <= recording.span_s + 4.0
    moved = decode_asterix(shift_times(recording, shift)).plots
    original = decode_asterix(data).plots
    np.testing.assert_allclose(moved["time_of_day_s"] - original["time_of_day_s"], shift)
    np.testing.assert_array_equal(moved["range_m"], original["range_m"])
    with pytest.raises(ValueError, match="ASTERIX data block at byte 0"):
        scan_blocks(np.frombuffer(b"\x30\x00\x02", np.uint8))
    with pytest.raises(ValueError, match="datagram size"):
        datagram_plan(recording, 70000)


def test_replay_paces_loops_and_logs(small_scene, tmp_path):
    sensors, plots = small_scene
    path = tmp_path / "plots.parquet"
    plots.to_parquet(path)
    recording = load_recording(path, sensors)
    assert recording.records == len(plots)
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(2.0)
    received = []

    def listen():
        while True:
            try:
                received.append(receiver.recv(65536))
            except socket.timeout:
                return

    thread = threading.Thread(target=listen)
    thread.start()
    # 120 s at x100 is 1.2 s a pass; two passes
    replayer = Replayer(recording, receiver.getsockname(), speed=100.0, loop=True, loop_period_s=4.0,
                        send_log=tmp_path / "sent.bin")
    report = replayer.run(duration_s=2.0)
    thread.join()
    receiver.close()
    assert 1.9 <= report.elapsed_s <= 3.0 and report.passes == 2
    assert len(received) == report.datagrams and all(len(d) <= 1400 for d in received)
    decoded = decode_asterix(b"".join(received)).plots
    assert len(decoded["time"]) == report.records > len(plots)
    log = read_send_log(tmp_path / "sent.bin")
    assert len(log) == report.datagrams
    # the wall time of sending follows the record times at x100 (within 50 ms; sleeps wake late, not early)
    planned = log[0, 1] + (log[:, 0] - log[0, 0]) / 100.0
    assert np.all(log[:, 1] >= planned - 0.002) and np.percentile(log[:, 1] - planned, 99) < 0.05
    assert np.all(np.diff(log[:, 0]) >= 0)  # times go on across the loop
    with pytest.raises(ValueError, match="give --sensors"):
        load_recording(path)


def test_recorded_file_with_service_messages_and_adsb_counts_plots_apart(small_scene, tmp_path):
    """A simulated recording (``simulate --format asterix``) holds CAT034 and CAT021 records beside the plots."""
    import pandas as pd

    from skytrack.io.asterix.cat021 import cat021_blocks, encode_cat021

    sensors, plots = small_scene
    head = plots[plots["time"] < 10.0]
    service = pd.DataFrame({"time": [0.0, 4.0, 8.0], "sensor": "radar1", "message": "north_marker"})
    radar = encode_asterix(head, sensor_sac_sic(sensors), service=service)
    adsb = pd.DataFrame({"time": [1.0, 2.0], "icao24": ["4ca7b5", "3c6a01"], "lat": [48.9, 49.0],
                         "lon": [2.5, 2.6], "alt_m": [9000.0, 7000.0]})
    blocks = cat021_blocks(encode_cat021(adsb, (0, 101)))
    data = radar + (blocks if isinstance(blocks, bytes) else b"".join(blocks))
    (tmp_path / "feed.ast").write_bytes(data)
    recording = load_recording(tmp_path / "feed.ast")
    assert recording.plots == len(head) and recording.records == len(head) + 3 + 2
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    report = Replayer(recording, receiver.getsockname(), speed=1000.0).run()
    receiver.close()
    assert (report.plots, report.records) == (len(head), len(head) + 5)


def test_sector_blocks_and_datagrams_hold_at_most_their_span_of_plot_time(small_scene):
    # a radar sends each sector as it is swept: blocks cut at every 1/8 s, and datagrams that never
    # wait longer than that for their newest plot (at 1 x, whole 128-record blocks held ~6 s of plots)
    sensors, plots = small_scene
    mapping = sensor_sac_sic(sensors)
    whole = encode_recording(plots, mapping, max_records_per_block=128)
    cut = encode_recording(plots, mapping, max_records_per_block=128, block_span_s=0.125)
    for data, span in ((whole, None), (cut, 0.125)):
        recording = scan_blocks(np.frombuffer(data, np.uint8))
        decoded = decode_asterix(data).plots
        block = np.searchsorted(recording.block_starts, np.asarray(decoded["byte_offset"]), side="right") - 1
        time = np.asarray(decoded["time_of_day_s"])
        slot_of_block = np.full(block.max() + 1, -1.0)
        widest = max(np.ptp(time[block == k]) for k in np.unique(block))
        if span is None:
            assert widest > 1.0
        else:  # every block's plots lie in one 1/8 s slot of the time of day
            slots = np.floor(time / span)
            np.maximum.at(slot_of_block, block, slots)
            assert (slots == slot_of_block[block]).all() and widest < span
        np.testing.assert_array_equal(np.sort(time), np.sort(np.asarray(decode_asterix(whole).plots["time_of_day_s"])))
    recording = scan_blocks(np.frombuffer(cut, np.uint8))
    bounds, _ = datagram_plan(recording, 1400, max_span_s=0.25)
    first, last = recording.block_times[bounds[:-1]], recording.block_times[bounds[1:] - 1]
    assert (last - first <= 0.25).all() and len(bounds) - 1 > len(datagram_plan(recording, 1400, 1e9)[0]) - 1
    with pytest.raises(ValueError, match="block_span_s"):
        encode_recording(plots, mapping, block_span_s=0.0)

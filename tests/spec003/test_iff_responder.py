"""Spec 003 R18 and TV13 (c): the simulator's IFF responder (skytrack.sim.iff).

Monte Carlo rates are checked within 4 binomial standard errors; the stream properties
(the draws do not depend on the request mask or on the probabilities) are exact.
"""

import math

import numpy as np
import pytest

from skytrack.sim.iff import FOE, FRIEND, MODE3A_CODE_COUNT, interrogation_mask, mode3a_int, respond

STATUS = np.array([FRIEND, FOE, FRIEND])
CODE = np.array([mode3a_int("1234"), mode3a_int("5670"), mode3a_int("7777")])


def _objects(count: int, seed: int = 11) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, STATUS.size, count)


def _within_4se(successes: int, trials: int, p: float) -> bool:
    se = math.sqrt(p * (1.0 - p) / trials)
    return abs(successes / trials - p) <= 4.0 * se


def test_reply_fraction_is_p_reply_scalar_and_per_object():
    objects = _objects(200_000)
    status, code = respond(objects, np.ones(objects.size, bool), STATUS, CODE, np.random.default_rng(1), p_reply=0.9)
    replied = status >= 0
    assert _within_4se(int(replied.sum()), objects.size, 0.9)
    assert np.array_equal(replied, code >= 0)  # a reply carries both fields, a missing reply neither
    per_object = np.array([0.3, 0.6, 0.95])
    status, _ = respond(objects, np.ones(objects.size, bool), STATUS, CODE, np.random.default_rng(2), p_reply=per_object)
    for k, p in enumerate(per_object):
        mine = objects == k
        assert _within_4se(int((status[mine] >= 0).sum()), int(mine.sum()), p)


def test_without_errors_the_reply_is_the_truth():
    objects = _objects(10_000)
    status, code = respond(objects, np.ones(objects.size, bool), STATUS, CODE, np.random.default_rng(3), p_reply=1.0)
    assert np.array_equal(status, STATUS[objects]) and np.array_equal(code, CODE[objects])
    assert status.dtype == np.int8 and code.dtype == np.int32


def test_flip_and_code_corruption_rates():
    objects = _objects(200_000)
    status, code = respond(objects, np.ones(objects.size, bool), STATUS, CODE, np.random.default_rng(4),
                           p_reply=0.8, p_flip=0.1, p_code=0.2)
    replied = status >= 0
    n = int(replied.sum())
    flipped = status[replied] != STATUS[objects[replied]]
    corrupted = code[replied] != CODE[objects[replied]]
    assert _within_4se(int(flipped.sum()), n, 0.1)
    assert _within_4se(int(corrupted.sum()), n, 0.2)
    # a flip is friend <-> foe, never undetermined; flips and corruptions are independent draws
    assert set(np.unique(status[replied])) == {FRIEND, FOE}
    assert _within_4se(int((flipped & corrupted).sum()), n, 0.02)


def test_corrupted_codes_are_other_valid_codes_uniformly():
    count = 409_500  # 100 per other code
    objects = np.zeros(count, dtype=np.int64)
    _, code = respond(objects, np.ones(count, bool), STATUS, CODE, np.random.default_rng(5), p_reply=1.0, p_code=1.0)
    assert code.min() >= 0 and code.max() < MODE3A_CODE_COUNT
    assert not np.any(code == CODE[0])
    counts = np.bincount(code, minlength=MODE3A_CODE_COUNT)
    others = np.delete(counts, CODE[0])
    assert others.size == 4095 and others.min() > 0
    # Pearson chi-square over the 4095 other codes: 4094 degrees of freedom, within 4 SD of its mean
    expected = count / 4095
    statistic = float(np.sum((others - expected) ** 2 / expected))
    assert abs(statistic - 4094) <= 4.0 * math.sqrt(2 * 4094)


def test_unrequested_plots_false_plots_and_objects_without_iff_carry_nothing():
    objects = np.array([0, 1, 2, -1, -1, 3, 0])
    status_table = np.append(STATUS, -1)  # object 3 has no IFF transponder
    code_table = np.append(CODE, -1)
    requested = np.array([True, True, False, True, True, True, True])
    status, code = respond(objects, requested, status_table, code_table, np.random.default_rng(6), p_reply=1.0)
    assert status.tolist() == [FRIEND, FOE, -1, -1, -1, -1, FRIEND]
    assert code.tolist() == [CODE[0], CODE[1], -1, -1, -1, -1, CODE[0]]
    # an object without a code replies with its status only, even when codes are corrupted
    status, code = respond(np.array([0, 0]), np.ones(2, bool), STATUS[:1], np.array([-1]), np.random.default_rng(6),
                           p_reply=1.0, p_code=1.0)
    assert status.tolist() == [FRIEND, FRIEND] and code.tolist() == [-1, -1]


def test_false_plots_reply_with_false_reply_p():
    count = 100_000
    objects = np.full(count, -1)
    status, code = respond(objects, np.ones(count, bool), STATUS, CODE, np.random.default_rng(7), false_reply_p=0.3)
    replied = status >= 0
    assert _within_4se(int(replied.sum()), count, 0.3)
    assert np.array_equal(replied, code >= 0)
    assert _within_4se(int((status[replied] == FRIEND).sum()), int(replied.sum()), 0.5)
    assert code.max() < MODE3A_CODE_COUNT


def test_draws_do_not_depend_on_the_mask_or_the_probabilities():
    """R18 / TV13 (c): every plot is drawn for; the stream after the call and the replies of
    plots interrogated under both settings are identical."""
    objects = np.append(_objects(5000), np.full(500, -1))
    mask_a = np.random.default_rng(8).random(objects.size) < 0.5
    mask_b = np.random.default_rng(9).random(objects.size) < 0.7
    settings = [
        (mask_a, dict(p_reply=0.9)),
        (mask_b, dict(p_reply=0.9)),
        (mask_a, dict(p_reply=0.5, p_flip=0.2, p_code=0.3, false_reply_p=0.4)),
        (np.zeros(objects.size, bool), dict(p_reply=0.0)),
    ]
    after, results = [], []
    for mask, p in settings:
        rng = np.random.default_rng(10)
        results.append(respond(objects, mask, STATUS, CODE, rng, **p))
        after.append(rng.random(4))
    for values in after[1:]:
        assert np.array_equal(values, after[0])
    both = mask_a & mask_b
    assert np.array_equal(results[0][0][both], results[1][0][both])
    assert np.array_equal(results[0][1][both], results[1][1][both])
    # lowering p_reply keeps a subset of the same replies (coupled through the same uniforms)
    fewer = results[2][0] >= 0
    assert np.all(results[0][0][fewer & (objects >= 0)] >= 0)
    assert np.all(results[3][0] == -1)


def test_validation():
    objects = np.array([0, 1])
    mask = np.ones(2, bool)
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="p_flip must lie in"):
        respond(objects, mask, STATUS, CODE, rng, p_flip=1.5)
    with pytest.raises(ValueError, match="one value per object"):
        respond(objects, mask, STATUS, CODE, rng, p_reply=[0.5, 0.5])
    with pytest.raises(ValueError, match="true_object"):
        respond(np.array([0, 3]), mask, STATUS, CODE, rng)
    with pytest.raises(ValueError, match="true_code"):
        respond(objects, mask, STATUS, np.array([0, 4096, 1]), rng)


def test_interrogation_policies():
    t = np.array([0.0, 39.9, 40.0, 60.0, 80.0, 80.1, 130.0])
    assert interrogation_mask(t, "always").all() and not interrogation_mask(t, "never").any()
    assert interrogation_mask(t, [[40, 80], [120, 140]]).tolist() == [False, False, True, True, True, False, True]
    with pytest.raises(ValueError, match="interrogation policy"):
        interrogation_mask(t, "track")

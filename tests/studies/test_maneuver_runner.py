"""Spec 004 R20-R22 study runner: seeded measurements (R21), two-point start, NIS/NEES consistency on a matched
model, gating and track loss, MACs per track update, set estimates, every catalogue filter (§6 defaults)."""

import numpy as np
import pytest
from scipy.stats import chi2

from skytrack.core import linalg
from skytrack.geo.polar import cartesian_to_polar, polar_to_cartesian
from skytrack.studies.maneuver.filters import CATALOG, FilterSetting, FilterSpec
from skytrack.studies.maneuver.measurements import simulate_measurements, standard_noise
from skytrack.studies.maneuver.runner import (
    FIRST_SCAN,
    RunOptions,
    _loss,
    run_filter,
    two_point_initiation,
)
from skytrack.studies.maneuver.scenarios import SensorSpec, named_cases, scripted_case
from skytrack.studies.maneuver.trajectory import straight


def straight_case(duration=40.0, dt=1.0):
    return scripted_case("test", "straight", (-10_000.0, 40_000.0, 6_000.0), (250.0, 0.0, 0.0), [straight(duration)], dt,
                         SensorSpec())


def build(spec: FilterSpec, case, meas):
    return spec.build(FilterSetting(case.dt, meas.R[0]))[0]


def test_run_r_uses_its_own_seed_sequence_child():
    noise = standard_noise(7, 5, 12)
    for r in range(5):
        rng = np.random.default_rng(np.random.SeedSequence(7).spawn(5)[r])
        assert np.array_equal(noise[:, r], rng.standard_normal((12, 3)))
    assert np.array_equal(standard_noise(7, 3, 12), noise[:, :3])  # a run does not depend on how many there are


def test_polar_measurements_are_consistent_with_their_linearised_covariance():
    case = straight_case(4.0)
    meas = simulate_measurements(case, 4000, 11)
    error = meas.z - case.truth.position[:, None, :]
    d2 = np.einsum("kri,kri->kr", error, np.linalg.solve(meas.R, error[..., None])[..., 0])
    assert abs(d2.mean() - 3.0) < 0.06  # chi2_3 mean; sd of the mean of 20 000 draws 0.017
    assert not np.allclose(meas.R[0, 0], meas.R[0, 1])  # R is evaluated at the measured plot
    # J diag(sigma^2) J^T at the true position, J by central differences of polar_to_cartesian
    r, az, el = cartesian_to_polar(*case.truth.position[0])
    polar, step = np.array([r, az, el]), np.array([1.0, 1e-7, 1e-7])
    J = np.column_stack([(np.array(polar_to_cartesian(*(polar + e))) - np.array(polar_to_cartesian(*(polar - e)))) / (2 * h)
                         for e, h in zip(np.diag(step), step)])
    expected = J @ np.diag([25.0**2, 1.5e-3**2, 1.5e-3**2]) @ J.T
    assert np.allclose(meas.R[0].mean(axis=0), expected, rtol=0, atol=0.01 * expected.max())
    cart = simulate_measurements(case, 6, 11, mode="cartesian", cartesian_sigma_m=50.0)
    assert np.array_equal(cart.R, np.broadcast_to(2500.0 * np.eye(3), cart.R.shape))
    assert np.allclose(cart.z - case.truth.position[:, None], 50.0 * standard_noise(11, 6, case.scans))
    with pytest.raises(ValueError, match="sigma > 0"):
        simulate_measurements(case, 2, 1, mode="cartesian")
    bounded = simulate_measurements(case, 3000, 2, mode="cartesian_uniform", cartesian_sigma_m=100.0)
    radius = np.linalg.norm(bounded.z - case.truth.position[:, None], axis=-1)
    assert radius.max() <= 100.0 and np.mean(radius**3) == pytest.approx(100.0**3 / 2, rel=0.02)  # r^3 ~ U(0, 100^3)
    assert np.array_equal(bounded.R[0, 0], 1e4 * np.eye(3))


@pytest.mark.parametrize("order", [2, 3])
def test_two_point_initiation_layout(order):
    z0, z1 = np.array([[1.0, 2.0, 3.0]]), np.array([[11.0, 12.0, 23.0]])
    R = np.array([[[4.0, 1.0, 0.0], [1.0, 9.0, 0.0], [0.0, 0.0, 16.0]]])
    x, P = two_point_initiation(z0, z1, R, R, 2.0, order, accel_sigma=20.0)
    pos = np.arange(3) * order
    assert np.array_equal(x[0, pos], z1[0]) and np.array_equal(x[0, pos + 1], [5.0, 5.0, 10.0])
    assert np.array_equal(P[0][np.ix_(pos, pos)], R[0]) and np.array_equal(P[0][np.ix_(pos, pos + 1)], R[0] / 2)
    assert np.array_equal(P[0][np.ix_(pos + 1, pos + 1)], 2 * R[0] / 4)
    if order == 3:
        assert np.array_equal(np.diag(P[0])[pos + 2], [400.0] * 3) and np.all(x[0, pos + 2] == 0)
    with pytest.raises(ValueError, match="2 or 3 states"):
        two_point_initiation(z0, z1, R, R, 1.0, 4)


def test_matched_filter_is_consistent():
    """A straight target and a KF without process noise: the two-point start is the exact error covariance,
    so NEES ~ chi2_6 and NIS ~ chi2_3 (means 6 and 3; 400 runs x 28 scans, stated tolerances ~4 sd)."""
    case = straight_case(30.0)
    meas = simulate_measurements(case, 400, 5)
    spec = FilterSpec("kf-cv-0", "kalman", {"model": "dwna", "sigma_w": 0.0})
    run = run_filter(build(spec, case, meas), case, meas, label="kf-cv-0")
    nees, nis = run.nees[FIRST_SCAN:], run.nis[FIRST_SCAN:]
    assert abs(nees.mean() - 6.0) < 0.3 and abs(nis.mean() - 3.0) < 0.15
    low, high = chi2.ppf([0.025, 0.975], 400 * 6) / 400
    inside = (nees.mean(axis=1) >= low) & (nees.mean(axis=1) <= high)
    assert inside.mean() >= 0.8
    assert not run.lost.any() and np.isnan(run.nees[:FIRST_SCAN]).all()


def test_batch_rows_and_cost_per_track_do_not_depend_on_the_number_of_runs():
    case = named_cases("default", turn_g=(5.0,))[0]
    spec = CATALOG["kf-ca"]
    small, large = simulate_measurements(case, 3, 2), simulate_measurements(case, 9, 2)
    a = run_filter(build(spec, case, small), case, small, label="a")
    b = run_filter(build(spec, case, large), case, large, label="b")
    assert np.allclose(a.position_error[FIRST_SCAN:], b.position_error[FIRST_SCAN:, :3], rtol=0, atol=1e-9)
    assert a.madds_per_update == b.madds_per_update > 0
    one = simulate_measurements(case, 1, 2)
    filt = build(spec, case, one)
    state = filt.initiate(*two_point_initiation(one.z[0], one.z[1], one.R[0], one.R[1], 1.0, 3))
    from skytrack.models.converted import ConvertedPositionModel

    with linalg.counting() as ops:
        predicted = filt.predict(state, np.ones(1))
        innovation = filt.innovate(predicted, one.z[2], ConvertedPositionModel(3, 3), {"R": one.R[2]})
        filt.update(predicted, one.z[2], innovation)
    assert ops.madds == a.madds[FIRST_SCAN]


def test_loss_rule_and_gating_modes():
    flag = np.array([[1, 0, 1], [1, 1, 1], [0, 1, 1], [1, 1, 0], [1, 1, 1]], dtype=bool)
    lost, scan = _loss(flag, 3)
    assert lost.tolist() == [False, True, True] and scan.tolist() == [-1, 3, 2]
    case = named_cases("default", turn_g=(7.0,))[0]
    meas = simulate_measurements(case, 20, 3)
    spec = CATALOG["kf-cv"]
    off = run_filter(build(spec, case, meas), case, meas, label="kf-cv")
    on = run_filter(build(spec, case, meas), case, meas, label="kf-cv", options=RunOptions(gating="on"))
    assert off.used[FIRST_SCAN:].all() and off.lost.all()  # a 7 g turn against sigma_w = 1: eps far out of the gate
    assert on.lost.all() and not on.used[FIRST_SCAN:].all()
    for r in range(20):
        k = on.loss_scan[r]
        assert not on.used[k - 2:k + 1, r].any()
    gate = chi2.ppf(0.9999, 3)
    assert np.array_equal(on.in_gate[FIRST_SCAN:], on.nis[FIRST_SCAN:] <= gate)
    assert np.isnan(on.madds[FIRST_SCAN:][~on.used[FIRST_SCAN:].all(axis=1)]).all()  # cost counted on full batches only


def test_set_estimates_gate_on_the_filters_consistency_and_start_from_the_bounding_set():
    """Set-membership (R_b = 9 R bounds 3-sigma Gaussian errors): consistency d^2 < 1 is the gate, the truth is
    inside E(x, P) on (almost) every scan, NEES is not computed."""
    from skytrack.filters.set_membership import two_point_initial_set

    case = straight_case(25.0)
    meas = simulate_measurements(case, 50, 8)
    spec = CATALOG["set-membership"]
    filt = build(spec, case, meas)
    run = run_filter(filt, case, meas, label="sm", initiation=spec.initiation)
    assert run.estimate == "set" and np.isnan(run.nees).all() and np.isnan(run.nis).all()
    k = FIRST_SCAN
    x0, P0 = two_point_initial_set(meas.z[0], meas.z[1], 1.0, 9 * meas.R[1], 9 * meas.R[0])
    predicted = filt.predict(filt.initiate(x0, P0), np.ones(50))
    from skytrack.models.converted import ConvertedPositionModel

    d2 = filt.innovate(predicted, meas.z[k], ConvertedPositionModel(3, 2), {"R": meas.R[k]}).d2
    assert np.array_equal(run.consistency[k], d2) and np.array_equal(run.in_gate[k], d2 < 1)
    assert np.nanmean(run.contained[FIRST_SCAN:]) > 0.99
    with pytest.raises(ValueError, match="initiation"):
        run_filter(filt, case, meas, label="sm", initiation="one-point")


@pytest.mark.parametrize("label", sorted(CATALOG))
def test_every_catalogue_filter_runs_on_the_default_turn(label):
    """The §6 default parameters build every family, and the runner handles each (mixtures, constant gains,
    sets, banks): finite errors from scan 2, a cost per update, no error on 6 runs of a 5 g turn."""
    case = named_cases("default", turn_g=(5.0,))[0]
    meas = simulate_measurements(case, 6, 1)
    spec = CATALOG[label]
    run = run_filter(build(spec, case, meas), case, meas, label=label, r_scale=spec.r_scale, initiation=spec.initiation)
    assert np.isfinite(run.position_error[FIRST_SCAN:]).all() and np.isnan(run.position_error[:FIRST_SCAN]).all()
    assert run.madds_per_update > 0 and run.us_per_update > 0
    assert np.isfinite(run.nees[FIRST_SCAN:]).all() != (run.estimate == "set")


def test_derived_options():
    setting = FilterSetting(2.0, np.broadcast_to(np.diag([100.0, 400.0, 2500.0]), (4, 3, 3)))
    spec = CATALOG["alpha-beta-gamma"]
    filt, motion = spec.build(setting)
    assert motion.order == 3
    from skytrack.filters.alpha_beta_gains import kalata_alpha_beta_gamma

    expected = kalata_alpha_beta_gamma(np.array([10.0 * 4 / 10, 10.0 * 4 / 20, 10.0 * 4 / 50]))
    assert np.allclose(filt.alpha, expected[0], rtol=1e-12)
    with pytest.raises(ValueError, match="unknown derived option"):
        FilterSpec("x", "kalman", {"model": "dwna"}, derived=("sigma",))
    with pytest.raises(ValueError, match="filter 'bad': unknown filter kind"):
        FilterSpec("bad", "kalman-nope", {"model": "dwna"}).build(setting)

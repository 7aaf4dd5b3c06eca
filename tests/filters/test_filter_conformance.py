"""Conformance suite of the batched filter protocol (issue 5, item 8), over every registered filter.

The cases are built at collection time by :func:`conformance_cases` from ``FILTERS`` (registered
kind x motion model x ``compiled``), keeping only the filters whose ``capabilities`` say the
property means something, so a newly registered family is picked up without editing this file
(``test_new_filter_kind_is_picked_up`` shows it).  Each property is a ``check_*`` function of
``(kind, motion, compiled)``.

Tolerances: "relative" means ``|a - b| <= rtol * max|b|`` over the compared array (its largest
entry sets the scale), see :func:`assert_rel`.  Monte Carlo seeding: run ``r`` draws everything
from ``np.random.default_rng(np.random.SeedSequence(seed).spawn(runs)[r])``, so results do not
depend on how runs are batched.
"""

from __future__ import annotations

import contextlib
import dataclasses

import numpy as np
import pytest
from scipy import stats

from skytrack.core import linalg
from skytrack.filters.base import ListRecorder, MixtureState
from skytrack.filters.kalman import KalmanFilter
from skytrack.filters.registry import FILTERS, build_filter, register_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_velocity, singer

MOTIONS = {
    "cv2": lambda: constant_velocity(2, 1.0),
    "cv3": lambda: constant_velocity(3, 1.0),
    "singer3": lambda: singer(3, tau=20.0, sigma_a=3.0, discretization="exact"),
}
#: per-axis prior standard deviations (position m, velocity m/s, acceleration m/s^2)
AXIS_SIGMA = (100.0, 30.0, 3.0)


def conformance_cases(applies=None, compiled=(True, False)) -> list:
    """``pytest.param(kind, motion, compiled)`` for every registered kind whose filter satisfies ``applies``."""
    cases = []
    for kind in sorted(FILTERS):
        for motion in MOTIONS:
            for flag in compiled:
                filt = buildable(kind, motion, flag)
                if filt is not None and (applies is None or applies(filt)):
                    cases.append(pytest.param(kind, motion, flag, id=f"{kind}-{motion}-{'numba' if flag else 'numpy'}"))
    return cases


def buildable(kind, motion, compiled):
    """The filter of ``kind`` on ``motion``, or None when the family rejects that state space.

    Families with a fixed state layout (e.g. the m = 3 embedding of spec 004's multiple-model
    filters) raise ValueError for the motions they cannot use; every kind must accept at
    least one motion of :data:`MOTIONS` (``test_every_kind_has_a_conformance_motion``).
    """
    try:
        return build_filter(kind, MOTIONS[motion](), compiled=compiled)
    except ValueError:
        return None


def is_mixture(filt) -> bool:
    return filt.capabilities.multiple_model


def first_model(filt, motion):
    """The motion model truth is simulated from: the filter's ``matched_motion`` when it declares one
    (the model on which it is the consistent filter, e.g. a manoeuvre detector's quiescent model; see
    :class:`~skytrack.filters.base.BatchFilter`), else a multiple-model filter's first mode, else ``motion``."""
    matched = getattr(filt, "matched_motion", None)
    if matched is not None:
        return matched
    for name in ("modes", "members"):
        if hasattr(filt, name):
            return getattr(filt, name)[0].transition
    return motion


def kinds_cases() -> list:
    """(kind, motion) pairs, for properties comparing the two ``compiled`` settings."""
    return [pytest.param(kind, motion, id=f"{kind}-{motion}") for kind in sorted(FILTERS) for motion in MOTIONS
            if buildable(kind, motion, True) is not None]


# ---------------------------------------------------------------------------- helpers
class Case:
    def __init__(self, kind, motion, compiled, **options):
        self.motion = MOTIONS[motion]()
        self.filt = build_filter(kind, self.motion, compiled=compiled, **options)
        self.ndim, self.order, self.n = self.motion.ndim, self.motion.order, self.motion.dim
        self.model = ConvertedPositionModel(self.ndim, self.order)
        self.pos = self.motion.position_index

    def initial(self, rng, rows):
        x = np.zeros((rows, self.n))
        x[:, self.pos] = rng.uniform(-5e4, 5e4, (rows, self.ndim))
        x[:, self.pos + 1] = rng.normal(0.0, 150.0, (rows, self.ndim))
        sigma = np.tile(AXIS_SIGMA[: self.order], self.ndim) * rng.uniform(0.5, 2.0, (rows, 1))
        return self.filt.initiate(x, random_spd(rng, sigma))

    def measurement(self, rng, state, spread=1.0):
        """Random plots: the estimate's position plus noise drawn from a random R (spread x its sd)."""
        rows = len(state)
        R = random_spd(rng, rng.uniform(20.0, 200.0, (rows, self.ndim)))
        u = rng.standard_normal((rows, self.ndim)) * spread
        z = state.estimate().x[:, self.pos] + np.einsum("kij,kj->ki", np.linalg.cholesky(R), u)
        return z, R

    def cycle(self, state, dt, z, R, context=None):
        pred = self.filt.predict(state, dt)
        inn = self.filt.innovate(pred, z, self.model, {"R": R, **(context or {})})
        new, stats_ = self.filt.update(pred, z, inn)
        return pred, inn, new

    def run(self, rng, state, steps, dt_range=(0.1, 10.0), spread=(0.5, 3.0), check=None):
        for _ in range(steps):
            dt = rng.uniform(*dt_range, len(state))
            pred = self.filt.predict(state, dt)
            z, R = self.measurement(rng, pred, rng.uniform(*spread))
            state, _ = self.filt.update(pred, z, self.filt.innovate(pred, z, self.model, {"R": R}))
            if check is not None:
                check(state)
        return state


def random_spd(rng, sigma):
    """Random SPD matrices ``[K, n, n]`` with standard deviations ``sigma[K, n]`` and random correlations."""
    rows, n = sigma.shape
    A = rng.standard_normal((rows, n, n))
    C = 0.3 * np.eye(n) + A @ np.swapaxes(A, -1, -2) / n
    d = np.sqrt(np.einsum("kii->ki", C))
    C = C / (d[:, :, None] * d[:, None, :])
    return C * sigma[:, :, None] * sigma[:, None, :]


def assert_rel(actual, expected, rtol, what=""):
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape, what
    if expected.dtype.kind in "biu":
        assert np.array_equal(actual, expected), what
        return
    scale = max(float(np.max(np.abs(expected), initial=0.0)), 1e-300)
    err = float(np.max(np.abs(actual - expected), initial=0.0)) / scale
    assert err <= rtol, f"{what}: relative difference {err:.3e} > {rtol:.0e}"


def assert_state_rel(a, b, rtol, what=""):
    assert type(a) is type(b)
    for name, value in b.to_arrays().items():
        assert_rel(getattr(a, name), value, rtol, f"{what}.{name}")


def assert_state_equal(a, b):
    assert type(a) is type(b)
    for name, value in b.to_arrays().items():
        got = getattr(a, name)
        assert got.dtype == value.dtype and np.array_equal(got, value), name


def assert_spd(P, what="", semidefinite=False):
    """Symmetric to 1e-9 and positive definite (``semidefinite``: eigenvalues >= -1e-9 x the largest)."""
    asym = np.max(np.abs(P - np.swapaxes(P, -1, -2)), axis=(-1, -2)) / np.max(np.abs(P), axis=(-1, -2))
    assert np.all(asym <= 1e-9), f"{what}: asymmetry {asym.max():.2e}"
    eig = np.linalg.eigvalsh(P)
    if semidefinite:
        assert np.all(eig[..., 0] >= -1e-9 * eig[..., -1]), f"{what}: not positive semidefinite"
    else:
        assert eig.min() > 0.0, f"{what}: not positive definite"


def sqrt_psd(Q):
    w, U = np.linalg.eigh(Q)
    return U * np.sqrt(np.clip(w, 0.0, None))[..., None, :]


def gens(seed, runs):
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)]


# ---------------------------------------------------------------------------- properties
def check_zero_dt_identity(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(1)
    state = case.run(rng, case.initial(rng, 6), 5)
    same = case.filt.predict(state, np.zeros(len(state)))
    # exact for F(0) = I, Q(0) = 0; the IMM's Pi(0) = expm(0) comes from an eigendecomposition
    assert_state_rel(same, state, 1e-12, "predict(0)")
    assert_rel(same.estimate().x, state.estimate().x, 1e-12, "x")
    assert_rel(same.estimate().P, state.estimate().P, 1e-12, "P")
    return float(np.max(np.abs(same.estimate().x - state.estimate().x) / (1.0 + np.abs(state.estimate().x))))


def check_huge_r_is_noop(kind, motion, compiled):
    """With R = 1e12 I the estimate moves by < 1e-3 of its standard deviations (correlation units for P).

    Bound for one Gaussian: |dx_i| / sd_i <= sqrt(lmax(H P H^T)) |nu| / lmin(R) and
    |dP_ij| / (sd_i sd_j) <= lmax(H P H^T) / lmin(R): up to ~2e-5 here (psi on, position variance
    ~1e7 m^2); a mixture also shifts its weights by the same order.  1e-3 leaves a factor 40.
    """
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(2)
    pred = case.filt.predict(case.run(rng, case.initial(rng, 6), 5), rng.uniform(0.1, 10.0, 6))
    z, _ = case.measurement(rng, pred, 3.0)
    R = np.broadcast_to(1e12 * np.eye(case.ndim), (6, case.ndim, case.ndim)).copy()
    new, _ = case.filt.update(pred, z, case.filt.innovate(pred, z, case.model, {"R": R}))
    before, after = pred.estimate(), new.estimate()
    sd = np.sqrt(np.einsum("kii->ki", before.P))
    assert np.max(np.abs(after.x - before.x) / sd) < 1e-3
    assert np.max(np.abs(after.P - before.P) / (sd[:, :, None] * sd[:, None, :])) < 1e-3
    # the same plots with their own R do move it (the property is not vacuous)
    z, R = case.measurement(rng, pred, 3.0)
    moved = case.filt.update(pred, z, case.filt.innovate(pred, z, case.model, {"R": R}))[0].estimate()
    # a set-membership filter's set may be far wider than the plot noise: then its centre moves
    # little while the set shrinks by orders of magnitude, so a move of x or of P counts
    moved_x = np.max(np.abs(moved.x - before.x) / sd)
    moved_P = np.max(np.abs(moved.P - before.P) / (sd[:, :, None] * sd[:, None, :]))
    assert moved_x > 0.1 or moved_P > 0.1
    return float(np.max(np.abs(after.x - before.x) / sd))


def check_covariance_spd(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(3)
    steps = []

    # Multiple-model filters on 3 states per axis embed CV and CT with zero acceleration rows
    # (spec 004 §3.3 B): such a mode knows its acceleration exactly, so its covariance -- and a
    # bank's output while only that member is active -- is singular there: semidefinite.
    embedded = is_mixture(case.filt) and case.order == 3

    def check(state):
        assert_spd(state.estimate().P, f"estimate step {len(steps)}", semidefinite=embedded)
        if isinstance(state, MixtureState):
            assert_spd(state.P.reshape(-1, case.n, case.n), "mode covariance", semidefinite=embedded)
        steps.append(1)

    case.run(rng, case.initial(rng, 8), 200, check=check)
    return len(steps)


def check_batch_equals_rows(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(4)
    state = case.run(rng, case.initial(rng, 5), 4, spread=(1.0, 6.0))
    dt = rng.uniform(0.1, 10.0, 5)
    z, R = case.measurement(rng, case.filt.predict(state, dt), 2.0)
    pred, inn, new = case.cycle(state, dt, z, R)
    single = [case.cycle(state.take([r]), dt[[r]], z[[r]], R[[r]]) for r in range(5)]
    assert_state_rel(type(pred).concat([s[0] for s in single]), pred, 1e-12, "predict")
    for field in ("d2", "loglik", "logdet", "nu", "S"):
        assert_rel(np.concatenate([getattr(s[1], field) for s in single]), getattr(inn, field), 1e-12, field)
    assert_state_rel(type(new).concat([s[2] for s in single]), new, 1e-12, "update")
    rows_d2 = np.concatenate([s[1].d2 for s in single])
    return float(np.max(np.abs(rows_d2 - inn.d2) / (1.0 + np.abs(inn.d2))))


def check_same_seed_same_output(kind, motion, compiled):
    outputs = []
    for _ in range(2):
        case = Case(kind, motion, compiled)
        rng = np.random.default_rng(5)
        outputs.append(case.run(rng, case.initial(rng, 6), 30))
    assert_state_equal(outputs[0], outputs[1])
    return outputs[0].estimate().x, outputs[1].estimate().x


def check_nees(kind, motion, compiled, runs=200, steps=50, dt=2.0, seed=20240605):
    """Time-averaged NEES of the estimate over ``runs`` rows simulated from the filter's motion model."""
    case = Case(kind, motion, compiled)
    filt, n, ndim = case.filt, case.n, case.ndim
    sim = first_model(filt, case.motion)
    F = sim.F_batch(np.array([dt]))[0]
    Qs = sqrt_psd(sim.Q_batch(np.array([dt]))[0])
    H = np.zeros((ndim, n))
    H[np.arange(ndim), case.pos] = 1.0
    sigma0 = np.tile(AXIS_SIGMA[: case.order], ndim)
    e0, w, v, R = [], [], [], []
    for g in gens(seed, runs):  # run r's numbers come only from its own spawned generator
        e0.append(g.standard_normal(n))
        w.append(g.standard_normal((steps, n)))
        v.append(g.standard_normal((steps, ndim)))
        R.append(np.diag(g.uniform(30.0, 80.0, ndim) ** 2))
    e0, w, v, R = map(np.array, (e0, w, v, R))
    Rs = np.linalg.cholesky(R)
    xhat = np.zeros((runs, n))
    xhat[:, case.pos + 1] = 150.0
    truth = xhat + e0 * sigma0
    state = filt.initiate(xhat, np.broadcast_to(np.diag(sigma0**2), (runs, n, n)).copy())
    nees = []
    for k in range(steps):
        truth = truth @ F.T + w[:, k] @ Qs.T
        z = truth @ H.T + np.einsum("kij,kj->ki", Rs, v[:, k])
        _, _, state = case.cycle(state, np.full(runs, dt), z, R)
        est = state.estimate()
        e = truth - est.x
        nees.append(np.mean(np.einsum("ki,ki->k", e, np.linalg.solve(est.P, e[..., None])[..., 0])))
    return float(np.mean(nees)), n


# ---------------------------------------------------------------------------- tests
@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(lambda f: f.capabilities.zero_dt_identity))
def test_zero_dt_predict_is_identity(kind, motion, compiled):
    assert check_zero_dt_identity(kind, motion, compiled) <= 1e-12


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(lambda f: f.capabilities.gain_depends_on_r))
def test_huge_r_update_is_noop(kind, motion, compiled):
    assert check_huge_r_is_noop(kind, motion, compiled) < 1e-3


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(lambda f: f.capabilities.has_covariance))
def test_covariance_stays_spd_over_200_random_cycles(kind, motion, compiled):
    assert check_covariance_spd(kind, motion, compiled) == 200  # every cycle checked


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases())
def test_batch_of_n_equals_n_batches_of_one(kind, motion, compiled):
    assert check_batch_equals_rows(kind, motion, compiled) <= 1e-12


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases())
def test_same_seed_same_output(kind, motion, compiled):
    first, second = check_same_seed_same_output(kind, motion, compiled)
    assert np.array_equal(first, second)


@pytest.mark.parametrize("kind,motion", kinds_cases())
def test_compiled_equals_numpy_reference(kind, motion):
    """Each step of the compiled filter on the reference filter's inputs, dt in [-10, 10] s (backwards too)."""
    fast, ref = Case(kind, motion, True), Case(kind, motion, False)
    rng = np.random.default_rng(6)
    state = ref.initial(rng, 7)
    for step in range(12):
        dt = rng.uniform(-10.0, 10.0, len(state))
        pred_ref, pred_fast = ref.filt.predict(state, dt), fast.filt.predict(state, dt)
        assert_state_rel(pred_fast, pred_ref, 1e-10, f"predict {step}")
        z, R = ref.measurement(rng, pred_ref, rng.uniform(0.5, 4.0))
        inn_ref = ref.filt.innovate(pred_ref, z, ref.model, {"R": R})
        inn_fast = fast.filt.innovate(pred_ref, z, fast.model, {"R": R})
        for field in ("nu", "S", "chol", "d2", "logdet", "loglik"):
            assert_rel(getattr(inn_fast, field), getattr(inn_ref, field), 1e-10, f"{field} {step}")
        new_ref, stats_ref = ref.filt.update(pred_ref, z, inn_ref)
        new_fast, stats_fast = fast.filt.update(pred_ref, z, inn_fast)
        assert_state_rel(new_fast, new_ref, 1e-10, f"update {step}")
        assert_rel(stats_fast.nis, stats_ref.nis, 1e-10, "nis")
        state = new_ref
    assert step == 11  # all twelve cycles compared

@pytest.mark.parametrize("kind,motion,compiled", conformance_cases())
def test_recorder_only_observes(kind, motion, compiled):
    """A ListRecorder changes no output (the compiled update falls back to numpy when recording, hence
    1e-10), and every event names rows of the batch it came from."""
    plain, recorded = Case(kind, motion, compiled), Case(kind, motion, compiled)
    recorded.filt.recorder = ListRecorder()
    outputs = []
    for case in (plain, recorded):
        rng = np.random.default_rng(14)
        outputs.append(case.run(rng, case.initial(rng, 6), 15, spread=(0.5, 8.0)))
    assert_state_rel(outputs[1], outputs[0], 1e-10, "recorded")
    assert recorded.filt.recorder.events  # gains, switches or mode probabilities over 15 cycles
    for channel, rows, values in recorded.filt.recorder.events:
        assert isinstance(channel, str) and rows.min() >= 0 and rows.max() < 6
        assert all(len(v) == len(rows) for v in values.values())


def nees_cases():
    return conformance_cases(lambda f: f.capabilities.has_covariance and not is_mixture(f)
                             and f.capabilities.matched_consistent)


@pytest.mark.parametrize("kind,motion,compiled", nees_cases())
def test_nees_consistent_on_matched_model(kind, motion, compiled):
    """Two-sided 95 % interval for the mean NEES of M = 200 rows (issue 7; spec 004 R20's band):
    chi2.ppf([0.025, 0.975], M n) / M, i.e. [3.618, 4.401] for n = 4, [5.529, 6.489] for n = 6,
    [8.422, 9.597] for n = 9.  It holds for each step's row average; the 50-step time average of
    these correlated averages has a variance no larger than one step's, so the interval is
    (slightly) conservative for it.  Truth comes from :func:`first_model` (a filter's
    ``matched_motion`` when it declares one).  One fixed seed: the test is deterministic.
    (kalman-psi stays consistent: on the matched model psi seldom switches.)"""
    value, n = check_nees(kind, motion, compiled)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 200 * n) / 200
    assert lo <= value <= hi, (value, lo, hi)


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(is_mixture))
def test_mixture_nees_on_first_mode_model(kind, motion, compiled):
    """Truth from mode 0's model only.  The moment-matched covariance keeps the high-noise mode at a
    few per cent (mixing leaks dt/60 s of weight into it every step, and its covariance is 3000x
    larger), so the estimate is conservative on a mode-0 path: observed NEES ~ 0.5 n.  The bound is
    [0.3 n, upper 99 % chi-square limit of the matched Kalman filter]: never overconfident, and not
    degenerate (a mixture covariance dominated by the wrong mode would go far below 0.3 n)."""
    value, n = check_nees(kind, motion, compiled)
    hi = stats.chi2.ppf(0.995, 200 * n) / 200
    assert 0.3 * n <= value <= hi, (value, n)


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases())
def test_state_saves_and_reloads_identically(kind, motion, compiled, tmp_path):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(7)
    state = case.run(rng, case.initial(rng, 6), 6, spread=(1.0, 6.0))
    arrays = state.to_arrays()
    assert set(arrays) == {f.name for f in dataclasses.fields(state)}
    assert_state_equal(type(state).from_arrays(arrays), state)
    np.savez(tmp_path / "state.npz", **arrays)
    with np.load(tmp_path / "state.npz") as saved:
        loaded = case.filt.state_type.from_arrays(dict(saved))
    assert_state_equal(loaded, state)
    # resuming from the checkpoint gives bit-identical results
    dt = rng.uniform(0.1, 10.0, 6)
    z, R = case.measurement(rng, case.filt.predict(state, dt))
    assert_state_equal(case.cycle(loaded, dt, z, R)[2], case.cycle(state, dt, z, R)[2])
    missing = sorted(arrays)[0]
    with pytest.raises(ValueError):
        type(state).from_arrays({k: v for k, v in arrays.items() if k != missing})


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(compiled=(True,)))
def test_take_put_concat_round_trip(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(8)
    state = case.run(rng, case.initial(rng, 7), 3)
    other = case.run(rng, case.initial(rng, 7), 3)
    order = rng.permutation(7)
    assert len(state.take(order[:3])) == 3
    assert_state_equal(type(state).concat([state.take(order[:3]), state.take(order[3:])]), state.take(order))
    assert_state_equal(state.take(np.arange(7) % 2 == 0), state.take([0, 2, 4, 6]))
    copy = state.copy()
    copy.put(order[:3], other.take(order[:3]))
    assert_state_equal(copy.take(order[:3]), other.take(order[:3]))
    assert_state_equal(copy.take(order[3:]), state.take(order[3:]))
    copy.put(order[:3], state.take(order[:3]))
    assert_state_equal(copy, state)


def test_checkpoint_does_not_alias_the_state():
    """An in-memory checkpoint must not change when the state is later modified in place (put)."""
    case = Case("kalman", "cv2", True)
    rng = np.random.default_rng(9)
    state = case.initial(rng, 3)
    checkpoint = state.to_arrays()
    saved = {k: v.copy() for k, v in checkpoint.items()}
    state.put([0], case.initial(rng, 1))
    assert all(np.array_equal(checkpoint[k], saved[k]) for k in saved)


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(compiled=(True,)))
def test_innovation_take_equals_innovating_those_rows(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(10)
    pred = case.filt.predict(case.run(rng, case.initial(rng, 6), 3), rng.uniform(0.1, 10.0, 6))
    z, R = case.measurement(rng, pred, 2.0)
    full = case.filt.innovate(pred, z, case.model, {"R": R})
    for rows in (np.array([4, 1]), np.array([True, False, True, True, False, False])):
        taken = full.take(rows)
        alone = case.filt.innovate(pred.take(rows), z[rows], case.model, {"R": R[rows]})
        assert len(taken) == len(alone)
        for field in ("nu", "S", "chol", "d2", "logdet", "loglik", "m", "H", "R"):
            assert_rel(getattr(taken, field), getattr(alone, field), 1e-12, field)
        assert_state_equal(taken.predicted, alone.predicted)
        assert set(taken.extra) == set(alone.extra)
        by_alone = case.filt.update(alone.predicted, z[rows], alone)[0]
        assert_state_rel(case.filt.update(taken.predicted, z[rows], taken)[0], by_alone, 1e-12, "update")
        assert_state_rel(case.filt.update(pred, z, full)[0].take(rows), by_alone, 1e-12, "rows of the full update")


@pytest.mark.parametrize("kind,motion,compiled", conformance_cases(is_mixture, compiled=(True,)))
def test_mixture_estimate_is_moment_matched(kind, motion, compiled):
    case = Case(kind, motion, compiled)
    rng = np.random.default_rng(11)
    # 8 cycles: a static bank's divergence test starts after W + 5 = 10 scans, so no member is off yet
    state = case.run(rng, case.initial(rng, 5), 8, spread=(0.5, 8.0))
    est = state.estimate()
    # rows where at least two modes carry weight, so that the spread-of-means term matters
    mixed = np.flatnonzero(np.sort(state.mu, axis=1)[:, -2] > 1e-6)
    assert mixed.size >= 3, "modes must differ for this check to mean something"
    # a bank's members may be of any family: their own estimates are the components
    mode_x, mode_P = state.member_estimates() if hasattr(state, "member_estimates") else (state.x, state.P)
    for r in mixed:
        mu, xs, Ps = state.mu[r], mode_x[r], mode_P[r]
        x = sum(mu[j] * xs[j] for j in range(len(mu)))
        P = sum(mu[j] * (Ps[j] + np.outer(xs[j] - x, xs[j] - x)) for j in range(len(mu)))
        assert_rel(est.x[r], x, 1e-12, "x")
        assert_rel(est.P[r], P, 1e-12, "P")
        assert np.max(np.abs(est.P[r] - Ps[0])) > 0.0


@pytest.mark.parametrize("kind,motion", kinds_cases())
def test_reference_path_counts_shape_implied_multiply_adds(kind, motion):
    """core.linalg counts every reference step of a Kalman-family filter; zero would mean a bypass."""
    case = Case(kind, motion, False)
    rng = np.random.default_rng(12)
    pred = case.filt.predict(case.initial(rng, 4), np.ones(4))
    z, R = case.measurement(rng, pred)
    with linalg.counting() as ops:
        case.filt.update(pred, z, case.filt.innovate(pred, z, case.model, {"R": R}))
    # counts are floats (R22: a Cholesky costs n^3/3), so the total depends on summation order
    assert ops.madds > 0 and ops.madds == pytest.approx(sum(ops.by_name.values()), rel=1e-12)
    if kind == "kalman":
        k, n, m = 4, case.n, case.ndim
        expected = k * (m * n * n + m * n * m + m**3 / 3 + m * m + m)  # innovate: sandwich, cholesky, d2 (R22)
        expected += k * (n * n * m + 2 * m * m * n + n * m + n * m * n)  # P H^T, cho_solve, K nu, K H
        expected += k * (n * m * m + n * m * n) + k * 2 * n**3  # sandwich(K, R), sandwich(A, P)
        assert ops.madds == expected


def test_compiled_path_is_counted_and_no_dearer_than_the_reference():
    """The compiled kernels report their own multiply-adds: the block-structured predict does
    fewer than the dense reference, the innovation the same."""
    counts = []
    for compiled in (True, False):
        case = Case("kalman", "cv3", compiled)
        rng = np.random.default_rng(13)
        state = case.initial(rng, 4)
        with linalg.counting() as ops:
            pred = case.filt.predict(state, np.ones(4))
            z, R = case.measurement(rng, pred)
            case.filt.update(pred, z, case.filt.innovate(pred, z, case.model, {"R": R}))
        counts.append(ops.madds)
    assert 0 < counts[0] < counts[1]


# ---------------------------------------------------------------------------- registry pick-up
@contextlib.contextmanager
def registered_test_kalman():
    """A test-only Kalman family under kind "test-kalman", removed from FILTERS afterwards."""

    class TestKalman(KalmanFilter):
        kind = "test-kalman"

    register_filter("test-kalman")(lambda motion, compiled=True: TestKalman(motion, compiled=compiled))
    try:
        yield "test-kalman"
    finally:
        FILTERS.pop("test-kalman", None)


@pytest.fixture
def registered_kind():
    with registered_test_kalman() as kind:
        yield kind


def test_new_filter_kind_is_picked_up(registered_kind):
    ids = [p.id for p in conformance_cases()]
    assert len(ids) == sum(buildable(k, m, f) is not None for k in FILTERS for m in MOTIONS for f in (True, False))
    assert sum(p.values[0] == registered_kind for p in conformance_cases()) == len(MOTIONS) * 2
    assert f"{registered_kind}-cv2-numba" in ids and f"{registered_kind}-singer3-numpy" in ids
    assert any(p.values[0] == registered_kind for p in conformance_cases(lambda f: f.capabilities.zero_dt_identity))
    assert sum(p.values[0] == registered_kind for p in kinds_cases()) == len(MOTIONS)
    # and the properties run on it
    check_zero_dt_identity(registered_kind, "cv3", True)
    check_same_seed_same_output(registered_kind, "cv2", False)
    with pytest.raises(ValueError, match="registered twice"):
        register_filter(registered_kind)(lambda motion: None)


@pytest.mark.parametrize("kind", sorted(FILTERS))
def test_every_kind_has_a_conformance_motion(kind):
    assert any(buildable(kind, motion, flag) is not None for motion in MOTIONS for flag in (True, False)), kind


def test_test_kind_is_removed_afterwards():
    before = sorted(FILTERS)
    with registered_test_kalman() as kind:
        assert sorted(FILTERS) == sorted(before + [kind])
    assert sorted(FILTERS) == before
    assert all(p.values[0] != "test-kalman" for p in conformance_cases())

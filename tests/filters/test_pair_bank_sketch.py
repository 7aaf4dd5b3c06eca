"""Sketch, as a test, of a bank of identification pairs (spec 001) on the batched filter protocol.

Rows are pairs (radar track i, ADS-B track j).  Each row carries the joint ("same object",
theta = 1) filter of spec 001 R2-R4 over the common object state (2-D CV, n = 4), fed by the
reports of both tracks in time order.  It starts diffuse, in information form (R3a: cost
``c(x) = x^T Y x - 2 y^T x + c0`` from ``Y = 0``) and switches to covariance form once ``Y`` has full
rank; per row it accumulates the quadratic form ``J`` (R2), the degrees of freedom, and ``llr``,
the sum of per-report log-likelihood ratios ``ln p(z | same) - ln p(z | separate)`` of the
sequential test (R6 log-odds recursion), where the separate (per-track) filter's term comes from
the track bank.  The sketch's classes live in this file: :class:`PairState` (an ``ArrayState``)
and :class:`PairFilter` (a ``BatchFilter``, not registered).  Its covariance rows run the
protocol's own ``KalmanFilter``.  On one bank whose rows are the two joint pairs and the three
separate (per-track) filters, the sketch reproduces spec 001 TV-3a/3b (J, Lambda) to 1e-6.

Gaps found in the protocol for this use (for the identification issue):

1. ``estimate()`` must return one Gaussian per row, but a diffuse row has none until its
   information matrix reaches full rank.  The sketch returns NaN rows, so there is no validity
   mask for gating or output, and ``Capabilities`` cannot say "estimate partial".  Conformance
   properties that read the estimate (zero-dt, huge R, NEES) do not apply to such rows.
2. ``Innovation`` requires ``S``, its Cholesky factor, ``ln det S`` and the log-likelihood for
   every row, and these do not exist for information-form rows (infinite ``S``).  ``d2`` becomes
   the GLS cost increment, which is chi-square with ``m - (rank increase)`` degrees of freedom,
   not ``m``.  ``Innovation.m`` is the measured dimension; there is no per-row dof field, so the
   sketch stores it in ``extra``.
3. ``update(state, z, innovation)`` takes no context, so per-row inputs that only the caller
   has (the separate filter's log-likelihood of the same report) must travel from ``innovate`` to
   ``update`` through ``Innovation.extra``.
4. Accumulators (J, dof, llr) must be fields of the state, so that ``take``/``put``/``concat``/
   ``to_arrays`` carry them.  That works, but every family needs its own state subclass and has
   to re-wrap its inner filter's state (as ``ManoeuvreState`` does).  The protocol has no generic
   way to attach accumulator or metadata columns (track ids) to another family's state.
5. Pairs share tracks.  A report of track i updates every pair (i, .), and the separate filter
   of track i lives in another bank whose rows are tracks.  The protocol has no cross-bank row
   reference; the caller gathers rows (``np.flatnonzero(state.radar == i)``) and fans the track's
   innovation out with ``Innovation.take`` on repeated indices.  Rows of one batch have different
   last-update times, so the bank, not the state, must keep a per-row epoch to form ``dt``.
6. ``initiate(x, P)`` only builds Gaussian starts and takes no row metadata.  A diffuse start and
   the pair's track ids need another constructor (``initiate_diffuse``).  ``pair_init="fuse"``
   (R13) would build a state from two track states, which is another constructor again.
7. The measurement protocol gives ``h(x)`` and ``H`` at a point.  An information-form update
   needs a linear ``h`` (the sketch uses ``H`` at x = 0 and ``z - h(0)``), and nonlinear
   (polar/Doppler) rows have no linearisation point before full rank.
8. The transition protocol gives ``F`` and ``Q``.  The information time update (R3a) needs
   ``F^-1`` and a factorisation ``Q = G Q_w G^T`` with ``Q_w`` invertible.  The sketch inverts
   ``Q``, which fails for singular ``Q`` (Singer "paper" discretisation, dt = 0).
9. Recorder events carry row indices local to the batch passed in.  A bank that updates a
   subset (``take(rows)``) must map them back to pairs itself.  No stable row id reaches the
   recorder.
10. Two forms in one state leave stale columns (``Y``/``y`` after the switch, ``x``/``P`` before
    it).  ``to_arrays`` checkpoints them too; a ``full`` flag per row is the only guard.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from skytrack.core import linalg
from skytrack.filters.base import (ArrayState, BatchFilter, Capabilities, GaussianState, Innovation,
                                   UpdateStats)
from skytrack.filters.kalman import KalmanFilter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import MotionModel, constant_velocity

N_STATE = 4  # 2-D CV [x, vx, y, vy]
MODEL = ConvertedPositionModel(2, 2)


# ---------------------------------------------------------------------------- the sketch
def info_rank(Y: np.ndarray) -> np.ndarray:
    """Scale-invariant rank (R3a): eigenvalues of D^-1/2 Y D^-1/2, D = diag(Y) (zeros -> 1)."""
    d = np.einsum("kii->ki", Y).copy()
    d[d <= 0] = 1.0
    Yn = Y / np.sqrt(d[:, :, None] * d[:, None, :])
    eig = np.linalg.eigvalsh(Yn)
    return np.sum(eig > 1e-9 * np.maximum(eig[:, -1:], 1e-300), axis=1)


def info_cost(Y, y, c0):
    """J = c0 - y^T Y^+ y, with a generalised inverse built on the scaled Y (y lies in range(Y))."""
    d = np.einsum("kii->ki", Y).copy()
    d[d <= 0] = 1.0
    s = 1.0 / np.sqrt(d)
    G = s[:, :, None] * np.linalg.pinv(Y * s[:, :, None] * s[:, None, :], rcond=1e-9, hermitian=True) * s[:, None, :]
    return c0 - np.einsum("ki,kij,kj->k", y, G, y)


@dataclass
class PairState(ArrayState):
    """Joint filter of a pair of tracks: information form until full rank, covariance form after."""

    Y: np.ndarray  # [N, n, n] information matrix (valid while not full)
    y: np.ndarray  # [N, n] information vector
    c0: np.ndarray  # [N] constant of the GLS cost
    x: np.ndarray  # [N, n] covariance form (valid where full)
    P: np.ndarray  # [N, n, n]
    full: np.ndarray  # [N] bool
    J: np.ndarray  # [N] accumulated quadratic form of the joint filter
    dof: np.ndarray  # [N] int: measured components minus state dimension reached
    llr: np.ndarray  # [N] sum of ln p(z | same) - ln p(z | separate track filter)
    radar: np.ndarray  # [N] int track id (system 1)
    adsb: np.ndarray  # [N] int track id (system 2)

    def rank(self) -> np.ndarray:
        return np.where(self.full, self.x.shape[1], info_rank(self.Y))

    def estimate(self) -> GaussianState:
        """Defined only for rows of full rank: covariance-form rows, or Y^-1 for full-rank Y; NaN elsewhere."""
        x, P = self.x.copy(), self.P.copy()
        info = ~self.full
        ok = info & (info_rank(self.Y) == self.x.shape[1])
        P[ok] = np.linalg.inv(self.Y[ok])
        x[ok] = np.einsum("kij,kj->ki", P[ok], self.y[ok])
        x[info & ~ok], P[info & ~ok] = np.nan, np.nan
        return GaussianState(x, P)


@dataclass(eq=False)
class PairFilter(BatchFilter):
    """Joint pair filter; ``switch=False`` keeps the information form for good (a pure information filter)."""

    motion: MotionModel
    switch: bool = True

    kind = "pair-sketch"
    capabilities = Capabilities()
    state_type = PairState

    def __post_init__(self):
        self.kalman = KalmanFilter(self.motion, compiled=False)

    @property
    def state_dim(self) -> int:
        return self.motion.dim

    def initiate(self, x, P) -> PairState:  # prior mode (R3b); no place for the track ids
        Y = np.linalg.inv(P)
        return self._new(Y, np.einsum("kij,kj->ki", Y, x), np.array(x, float), np.array(P, float),
                         np.ones(len(x), bool), -np.ones(len(x), int), -np.ones(len(x), int))

    def initiate_diffuse(self, radar, adsb) -> PairState:
        K, n = len(radar), self.state_dim
        return self._new(np.zeros((K, n, n)), np.zeros((K, n)), np.full((K, n), np.nan), np.full((K, n, n), np.nan),
                         np.zeros(K, bool), np.asarray(radar), np.asarray(adsb))

    @staticmethod
    def _new(Y, y, x, P, full, radar, adsb):
        K = len(Y)
        return PairState(Y, y, np.zeros(K), x, P, full, np.zeros(K), np.zeros(K, np.int64), np.zeros(K), radar, adsb)

    def predict(self, state: PairState, dt, context=None) -> PairState:
        dt = np.broadcast_to(self.transition_dt(dt), (len(state),))
        new = state.copy()
        f, i = state.full, ~state.full
        if f.any():
            g = self.kalman.predict(GaussianState(state.x[f], state.P[f]), dt[f])
            new.x[f], new.P[f] = g.x, g.P
        if i.any():  # R3a time update, G = I (Q invertible) or Q = 0
            Fi = np.linalg.inv(self.motion.F_batch(dt[i]))
            Q = self.motion.Q_batch(dt[i])
            M = np.swapaxes(Fi, -1, -2) @ state.Y[i] @ Fi
            u = np.einsum("kji,kj->ki", Fi, state.y[i])
            Y, y, c0 = M, u, state.c0[i].copy()
            noisy = np.any(Q != 0, axis=(1, 2))
            if noisy.any():
                Mn, un = M[noisy], u[noisy]
                A = Mn + np.linalg.inv(Q[noisy])
                Ai_M, Ai_u = np.linalg.solve(A, Mn), np.linalg.solve(A, un[..., None])[..., 0]
                Y, y = Y.copy(), y.copy()
                Y[noisy] = linalg.symmetrize(Mn - Mn @ Ai_M)
                y[noisy] = un - np.einsum("kij,kj->ki", Mn, Ai_u)
                c0[noisy] -= np.einsum("ki,ki->k", un, Ai_u)
            new.Y[i], new.y[i], new.c0[i] = Y, y, c0
        return new

    def innovate(self, state: PairState, z, model, context=None) -> Innovation:
        context = context or {}
        K, f = len(state), state.full
        h, H = model.evaluate(np.where(f[:, None], state.x, 0.0), context)  # linear model: h(0) for info rows
        R, m = model.noise(context), model.measured(context)
        nu = model.residual(np.asarray(z, float), h, context)
        S, L = np.full_like(R, np.nan), np.full_like(R, np.nan)
        d2, logdet, loglik = np.full(K, np.nan), np.full(K, np.nan), np.full(K, np.nan)
        if f.any():
            S[f] = linalg.sandwich(H[f], state.P[f], R[f])
            L[f] = linalg.cholesky(S[f])
            d2[f] = linalg.mahalanobis_chol(nu[f], L[f])
            logdet[f] = linalg.logdet_chol(L[f])
            loglik[f] = linalg.gaussian_loglik(d2[f], logdet[f], m[f])
        # tentative information update (Y += H^T V^-1 H, y += H^T V^-1 z, c0 += z^T V^-1 z)
        HtRi = np.swapaxes(H, -1, -2) @ np.linalg.inv(R)
        Y = state.Y + linalg.symmetrize(HtRi @ H)
        y = state.y + np.einsum("kij,kj->ki", HtRi, nu)
        c0 = state.c0 + np.einsum("ki,ki->k", nu, np.linalg.solve(R, nu[..., None])[..., 0])
        i = ~f
        d2[i] = info_cost(Y[i], y[i], c0[i]) - info_cost(state.Y[i], state.y[i], state.c0[i])
        dof = m - np.where(f, 0, info_rank(Y) - info_rank(state.Y))
        separate = np.broadcast_to(np.asarray(context.get("separate_loglik", np.nan), float), (K,))
        nu = np.where(f[:, None], nu, np.nan)
        return Innovation(nu, S, L, d2, logdet, loglik, m, H, R, state,
                          {"Y": Y, "y": y, "c0": c0, "dof": dof, "separate_loglik": separate.copy()})

    def update(self, state, z, innovation) -> tuple[PairState, UpdateStats]:
        pred: PairState = innovation.predicted
        new, f, i, e = pred.copy(), pred.full, ~pred.full, innovation.extra
        if f.any():  # covariance rows: the protocol's Kalman update, reusing this innovation
            inn = innovation
            sub = Innovation(inn.nu[f], inn.S[f], inn.chol[f], inn.d2[f], inn.logdet[f], inn.loglik[f], inn.m[f],
                             inn.H[f], inn.R[f], GaussianState(pred.x[f], pred.P[f]))
            g, _ = self.kalman.update(sub.predicted, np.asarray(z)[f], sub)
            new.x[f], new.P[f] = g.x, g.P
        new.Y[i], new.y[i], new.c0[i] = e["Y"][i], e["y"][i], e["c0"][i]
        new.J += innovation.d2
        new.dof += e["dof"]
        terms = f & np.isfinite(e["separate_loglik"])
        new.llr[terms] += innovation.loglik[terms] - e["separate_loglik"][terms]
        if self.switch:
            ready = i & (info_rank(new.Y) == self.state_dim)
            if ready.any():
                est = new.take(ready).estimate()
                new.x[ready], new.P[ready], new.full[ready] = est.x, est.P, True
        return new, UpdateStats(innovation.d2 / innovation.m)


# ---------------------------------------------------------------------------- test helpers
def cv_F(tau):
    """CV transition over tau (either sign), written out (not from skytrack)."""
    F = np.eye(N_STATE)
    F[0, 1] = F[2, 3] = tau
    return F


def reports(rng, count, start=(1000.0, 150.0, 2000.0, -60.0), offset=(0.0, 0.0)):
    """Merged stream of one pair: radar every 1 s (sigma 50 m), ADS-B at +0.3 s (sigma 20 m), Q = 0 truth."""
    out = []
    for k in range(count):
        system = k % 2
        t = k // 2 + 0.3 * system
        truth = cv_F(t) @ np.array(start)
        sigma = 50.0 if system == 0 else 20.0
        V = np.diag([sigma**2, (0.7 * sigma) ** 2])
        z = truth[[0, 2]] + np.array(offset) * system + np.linalg.cholesky(V) @ rng.standard_normal(2)
        out.append((t, system, z, V))
    return out


def gls(history, t):
    """Batch GLS of the reports so far at epoch t: N, x_hat, J (Q = 0), independent of the recursion."""
    H = np.zeros((2, N_STATE))
    H[0, 0] = H[1, 2] = 1.0
    N, b, zz, rows = np.zeros((N_STATE, N_STATE)), np.zeros(N_STATE), 0.0, []
    for ti, _, z, V in history:
        A = H @ cv_F(ti - t)
        Vi = np.linalg.inv(V)
        N, b, zz = N + A.T @ Vi @ A, b + A.T @ Vi @ z, zz + z @ Vi @ z
        rows.append((A, z, Vi))
    if np.linalg.matrix_rank(N) < N_STATE:
        return N, None, None
    x = np.linalg.solve(N, b)
    return N, x, sum((z - A @ x) @ Vi @ (z - A @ x) for A, z, Vi in rows)


def step(filt, state, dt, z, V, separate=np.nan):
    pred = filt.predict(state, dt)
    ctx = {"R": np.broadcast_to(V, (len(state), 2, 2)).copy(), "separate_loglik": separate}
    return filt.update(pred, np.broadcast_to(z, (len(state), 2)), filt.innovate(pred, np.broadcast_to(z, (len(state), 2)), MODEL, ctx))[0]


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ---------------------------------------------------------------------------- tests
def test_rank_grows_with_measurements_and_estimate_waits_for_full_rank():
    """Row 0: reports at t = 0, 0.3, 1 -> rank 0, 2, 4, 4.  Row 1: all reports at t = 0 -> rank stays 2
    (velocity unobservable).  dof = sum m - n once full: 2 + 2 + 2 - 4 = 2 for row 0, 6 - 2 = 4 for row 1."""
    filt = PairFilter(constant_velocity(2, 0.0))
    state = filt.initiate_diffuse([0, 1], [10, 10])
    assert state.rank().tolist() == [0, 0]
    assert np.isnan(state.estimate().x).all()
    rng = np.random.default_rng(1)
    ranks = []
    for dt in ([0.0, 0.0], [0.3, 0.0], [0.7, 0.0]):
        z = rng.normal(0.0, 50.0, 2)
        state = step(filt, state, np.array(dt), z, np.eye(2) * 2500.0)
        ranks.append(state.rank().tolist())
    assert ranks == [[2, 2], [4, 2], [4, 2]]
    assert state.full.tolist() == [True, False]
    assert state.dof.tolist() == [2, 4]
    est = state.estimate()
    assert np.isfinite(est.x[0]).all() and np.isfinite(est.P[0]).all()
    assert np.isnan(est.x[1]).all() and np.isnan(est.P[1]).all()
    assert np.linalg.eigvalsh(est.P[0]).min() > 0


@pytest.mark.parametrize("switch", [True, False])
def test_diffuse_start_equals_batch_gls(switch):
    """Q = 0: at every report the row's information matrix (before the switch), estimate, covariance
    and J equal the batch GLS over the reports so far (spec 001 R3 check, TV-3), to 1e-9."""
    filt = PairFilter(constant_velocity(2, 0.0), switch=switch)
    rng = np.random.default_rng(2)
    stream = reports(rng, 10)
    state, t_last = filt.initiate_diffuse([0], [0]), 0.0
    for k, (t, _, z, V) in enumerate(stream):
        state = step(filt, state, np.array([t - t_last]), z, V)
        t_last = t
        N, x, J = gls(stream[: k + 1], t)
        if not state.full[0]:
            assert rel(state.Y[0], N) < 1e-9
        if x is None:
            assert state.rank()[0] < N_STATE
            continue
        est = state.estimate()
        assert state.rank()[0] == N_STATE
        assert rel(est.x[0], x) < 1e-9 and rel(est.P[0], np.linalg.inv(N)) < 1e-9
        assert abs(state.J[0] - J) <= 1e-9 * max(J, 1.0)
        assert state.dof[0] == 2 * (k + 1) - N_STATE
    assert state.full[0] == switch


def test_information_form_equals_covariance_form_once_full_rank():
    """q = 25: a pure information filter (switch=False), the switching sketch and the protocol's
    KalmanFilter started from the first full-rank estimate agree on x, P and d^2 to 1e-9."""
    motion = constant_velocity(2, 25.0)
    info, switching = PairFilter(motion, switch=False), PairFilter(motion, switch=True)
    kalman = KalmanFilter(motion, compiled=True)
    rng = np.random.default_rng(3)
    stream = reports(rng, 24)
    a, b, t_last, g = info.initiate_diffuse([0], [0]), switching.initiate_diffuse([0], [0]), 0.0, None
    compared = 0
    for t, _, z, V in stream:
        dt = np.array([t - t_last])
        t_last = t
        ctx = {"R": V[None]}
        pa, pb = info.predict(a, dt), switching.predict(b, dt)
        ia, ib = info.innovate(pa, z[None], MODEL, ctx), switching.innovate(pb, z[None], MODEL, ctx)
        if g is not None:
            pg = kalman.predict(g, dt)
            ig = kalman.innovate(pg, z[None], MODEL, ctx)
            for inn in (ia, ib):
                assert abs(inn.d2[0] - ig.d2[0]) <= 1e-9 * max(ig.d2[0], 1.0)
            g = kalman.update(pg, z[None], ig)[0]
        a, b = info.update(pa, z[None], ia)[0], switching.update(pb, z[None], ib)[0]
        if g is None and a.rank()[0] == N_STATE:
            g = a.estimate()
            assert b.full[0]
            continue
        if g is not None:
            for est in (a.estimate(), b.estimate()):
                assert rel(est.x, g.x) < 1e-9 and rel(est.P, g.P) < 1e-9
            compared += 1
        assert abs(a.J[0] - b.J[0]) <= 1e-9 * max(b.J[0], 1.0)
    assert compared == 22 and not a.full[0] and b.full[0]  # 24 reports, full rank at the 2nd


def test_accumulator_is_the_sum_of_log_likelihood_ratios():
    """llr = sum over reports after the joint row reached full rank of ln N(nu; 0, S) of the joint
    filter (recomputed from the batch GLS and explicit formulas) minus the separate track filter's
    log-likelihood of the same report (a prior-mode KalmanFilter per track, passed via the context)."""
    filt = PairFilter(constant_velocity(2, 0.0))
    tracks = [KalmanFilter(constant_velocity(2, 0.0)) for _ in range(2)]
    rng = np.random.default_rng(4)
    stream = reports(rng, 12, offset=(120.0, -80.0))
    prior = (np.array([[1000.0, 0.0, 2000.0, 0.0]]), np.diag([1e6, 1e4, 1e6, 1e4])[None])
    separate = [t.initiate(*prior) for t in tracks]
    t_sep, state, t_last, expected, terms = [0.0, 0.0], filt.initiate_diffuse([0], [0]), 0.0, 0.0, 0
    for k, (t, system, z, V) in enumerate(stream):
        kf = tracks[system]
        pred_s = kf.predict(separate[system], np.array([t - t_sep[system]]))
        inn_s = kf.innovate(pred_s, z[None], MODEL, {"R": V[None]})
        separate[system], t_sep[system] = kf.update(pred_s, z[None], inn_s)[0], t
        before = state.full[0]
        state = step(filt, state, np.array([t - t_last]), z, V, separate=inn_s.loglik)
        t_last = t
        N, x, _ = gls(stream[:k], stream[k - 1][0]) if k else (None, None, None)
        assert before == (x is not None)
        if x is not None:
            F = cv_F(t - stream[k - 1][0])
            nu = z - (F @ x)[[0, 2]]
            S = (F @ np.linalg.inv(N) @ F.T)[np.ix_([0, 2], [0, 2])] + V
            joint = -0.5 * (nu @ np.linalg.inv(S) @ nu + np.log(np.linalg.det(S)) + 2 * np.log(2 * np.pi))
            expected += joint - inn_s.loglik[0]
            terms += 1
    assert terms == 10
    assert abs(state.llr[0] - expected) <= 1e-9 * abs(expected)


def test_pairs_sharing_a_track_update_only_their_rows():
    """Radar tracks {0, 1}, ADS-B tracks {10, 11, 12}; pairs (0,10), (0,11), (1,10), (1,12).  A report of
    one track updates exactly the pairs holding it (others bit-identical), with the track filter's
    innovation fanned out by ``Innovation.take`` on repeated rows; the bank equals one filter per pair."""
    filt = PairFilter(constant_velocity(2, 25.0))
    radar, adsb = np.array([0, 0, 1, 1]), np.array([10, 11, 10, 12])
    bank, epoch = filt.initiate_diffuse(radar, adsb), np.zeros(4)
    alone = [filt.initiate_diffuse(radar[[r]], adsb[[r]]) for r in range(4)]
    alone_epoch = np.zeros(4)
    track_filter = KalmanFilter(constant_velocity(2, 25.0))
    rng = np.random.default_rng(5)
    for k in range(16):
        system, track = k % 2, [0, 1, 10, 11, 12][rng.integers(0, 2) if k % 2 == 0 else 2 + rng.integers(0, 3)]
        t = 0.5 * k
        z, V = rng.normal([1000.0, 2000.0], 300.0), np.eye(2) * (50.0 if system == 0 else 20.0) ** 2
        rows = np.flatnonzero((bank.radar if system == 0 else bank.adsb) == track)
        if not len(rows):
            continue
        x0 = np.array([[1000.0, 0.0, 2000.0, 0.0]])
        track_state = track_filter.initiate(x0, np.diag([1e6, 1e4, 1e6, 1e4])[None])
        track_inn = track_filter.innovate(track_state, z[None], MODEL, {"R": V[None]}).take(np.zeros(len(rows), int))
        assert np.array_equal(track_inn.loglik, np.repeat(track_inn.loglik[:1], len(rows)))
        before = bank.copy()
        sub = bank.take(rows)
        pred = filt.predict(sub, t - epoch[rows])
        ctx = {"R": np.repeat(V[None], len(rows), 0), "separate_loglik": track_inn.loglik}
        zs = np.repeat(z[None], len(rows), 0)
        bank.put(rows, filt.update(pred, zs, filt.innovate(pred, zs, MODEL, ctx))[0])
        epoch[rows] = t
        others = np.setdiff1d(np.arange(4), rows)
        for name, value in before.take(others).to_arrays().items():
            assert np.array_equal(getattr(bank.take(others), name), value, equal_nan=value.dtype.kind == "f")
        for r in rows:
            alone[r] = step(filt, alone[r], np.array([t - alone_epoch[r]]), z, V, separate=track_inn.loglik[0])
            alone_epoch[r] = t
    together = PairState.concat(alone)
    for name, value in together.to_arrays().items():
        got = getattr(bank, name)
        if value.dtype.kind == "f":
            np.testing.assert_allclose(got, value, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(value)))
        else:
            assert np.array_equal(got, value)
    assert bank.full.any() and np.all(bank.J >= 0)


def test_take_put_concat_to_arrays_round_trip(tmp_path):
    filt = PairFilter(constant_velocity(2, 25.0))
    rng = np.random.default_rng(6)
    state = filt.initiate_diffuse(np.arange(5), np.arange(5) + 10)
    for k in range(3):  # rows 0-2 get 3 reports (full rank), rows 3-4 one (information form)
        rows = np.arange(5) if k == 0 else np.arange(3)
        sub = state.take(rows)
        state.put(rows, step(filt, sub, np.full(len(rows), 0.0 if k == 0 else 0.8), rng.normal(0, 100, 2),
                             np.eye(2) * 900.0, separate=-7.5))
    assert state.full.tolist() == [True, True, True, False, False]
    assert state.rank().tolist() == [4, 4, 4, 2, 2]
    arrays = state.to_arrays()

    def same(a, b):
        for name in arrays:
            u, v = getattr(a, name), getattr(b, name)
            assert u.dtype == v.dtype and np.array_equal(u, v, equal_nan=u.dtype.kind == "f"), name

    same(PairState.from_arrays(arrays), state)
    np.savez(tmp_path / "pairs.npz", **arrays)
    with np.load(tmp_path / "pairs.npz") as saved:
        loaded = PairState.from_arrays(dict(saved))
    same(loaded, state)
    assert loaded.radar.dtype.kind == "i" and loaded.full.dtype == bool
    order = np.array([4, 0, 3, 1, 2])
    same(PairState.concat([state.take(order[:2]), state.take(order[2:])]), state.take(order))
    copy = state.copy()
    copy.put([3, 4], state.take([0, 1]))
    same(copy.take([3, 4]), state.take([0, 1]))
    same(copy.take([0, 1, 2]), state.take([0, 1, 2]))
    # a reloaded bank continues bit-identically
    z, V = rng.normal(0, 100, 2), np.eye(2) * 900.0
    same(step(filt, loaded, np.full(5, 1.0), z, V, -3.0), step(filt, state, np.full(5, 1.0), z, V, -3.0))


TV3_RADAR = [(0.0, 1032, 2023), (1.0, 1068, 1891), (2.0, 1193, 1960), (3.0, 1367, 1895)]
TV3_ADSB = [(0.3, 1037, 2017), (1.3, 1155, 1931), (2.3, 1209, 1878), (3.3, 1322, 1849)]


@pytest.mark.parametrize("q,expected", [
    # J_joint same, J_joint diff, Q_eta, Q_xi (same and diff: an offset leaves it unchanged), Lambda same,
    # Lambda diff: spec 001 TV-3a
    (0.0, (10.723585, 52.200124, 4.629800, 3.947500, 2.146285, 43.622824)),
    (25.0, (10.665763, 52.129233, 4.618898, 3.889642, 2.157224, 43.620694)),
])
def test_spec001_tv3_on_one_bank(q, expected):
    """TV-3 of spec 001 on one bank of five diffuse rows: joint (radar, ADS-B same), joint (radar,
    ADS-B diff = same + (150, -100) m), radar alone, ADS-B same alone, ADS-B diff alone.  A report
    updates the rows holding its track.  Lambda = J_joint - J_radar - J_adsb (R4), to 1e-6 (TV-3)."""
    filt = PairFilter(constant_velocity(2, q))
    bank = filt.initiate_diffuse([0, 0, 0, -1, -1], [0, 1, -1, 0, 1])
    epoch = np.zeros(5)
    stream = sorted([(t, 0, 0, (x, y), 50.0) for t, x, y in TV3_RADAR]
                    + [(t, 1, 0, (x, y), 20.0) for t, x, y in TV3_ADSB]
                    + [(t, 1, 1, (x + 150, y - 100), 20.0) for t, x, y in TV3_ADSB])
    lam_same = []
    for t, system, track, z, sigma in stream:
        rows = np.flatnonzero((bank.radar if system == 0 else bank.adsb) == track)
        bank.put(rows, step(filt, bank.take(rows), t - epoch[rows], np.array(z, float), np.eye(2) * sigma**2))
        epoch[rows] = t
        if track == 0:
            lam_same.append(bank.J[0] - bank.J[2] - bank.J[3])
    J_same, J_diff, Q_eta, Q_xi, lam_s, lam_d = expected
    np.testing.assert_allclose(bank.J, [J_same, J_diff, Q_eta, Q_xi, Q_xi], rtol=0, atol=1e-6)
    np.testing.assert_allclose([bank.J[0] - bank.J[2] - bank.J[3], bank.J[1] - bank.J[2] - bank.J[4]],
                               [lam_s, lam_d], rtol=0, atol=1e-6)
    assert bank.rank().tolist() == [4] * 5 and bank.full.all()
    if q == 0.0:  # TV-3b: Lambda after each merged report (same case)
        np.testing.assert_allclose(lam_same, [0, 0, 0.628432, 2.975266, 2.486850, 1.138368, 3.499557, 2.146285],
                                   rtol=0, atol=1e-6)

"""NEES of the adaptive Kalman filters on their matched model, per adaptation rule (a benchmark of
statistics, not of speed; issue 7, spec 004 §3.3 F / L and R20's NEES band).

Scenario: the conformance suite's NEES property (``tests/filters/test_filter_conformance.py``,
``check_nees``), rebuilt here with the same random draws: ``--runs`` (200) rows simulated from the
filter's matched motion (its ``matched_motion`` when declared, else the motion itself: q = q0 = 1,
R-hat_0 = R), T = 2 s, 50 scans, per-row diagonal R with standard deviations uniform in 30-80 m, the
start 100 m / 30 m/s / 3 m/s^2 per axis off; NEES of the whole state averaged over rows and scans,
against the two-sided 95 % band ``chi2_{N n}^-1(0.025, 0.975) / N``.  Motions: ``cv2``, ``cv3``
(continuous white-noise acceleration, q = 1) and ``singer3`` (tau = 20 s, sigma_a = 3 m/s^2);
adaptive + input estimation on ``singer3`` (its own quiescent model).  AKF: kalman-adaptive,
AIE: adaptive-input-estimation.

Adaptation rules of the structured filter (:mod:`skytrack.filters.adaptive`):
``literal`` (weighting fading, prior_scans 0, no gate correction: §3.3 F as written), ``fading``
(the spec's d_k with skytrack's earlier defaults prior_scans = warm-up and the gate correction)
and ``information`` (the default).  Tables:

1. NEES per rule, kind and motion (the conformance test's seed);
2. where the fading rule's excess comes from: q-hat or R-hat pinned at the truth by their limits;
3. the information rule over ``--seeds`` seeds (mean, range, seeds inside the band);
4. scans 101-200 of a 200-scan run (does it stay consistent?);
5. precise measurements (sigma_r 3-8 m);
6. mean of the q sample on adaptation scans with q-hat pinned at the truth and R-hat adapting
   (singer3, 400 rows x 60 scans): the spec's sample from the update's own gain vs the information
   rule's from the previous R-hat's gain (and with R-hat pinned too);
7. a mis-specified start (study E6's R-hat_0 = 4 R, q0 = 25, and R-hat_0 = R / 4): R-hat / R and
   q-hat after 60 and 200 scans, CV with q = 1.

Usage:  python benchmarks/adaptive_nees.py [--runs 200] [--seeds 10]
"""

from __future__ import annotations

import argparse
import datetime as dt
import platform

import numpy as np
from machine import cpu_model, usable_cores  # benchmarks/machine.py
from rich.console import Console
from rich.table import Table
from scipy import stats

from skytrack.filters.base import ListRecorder
from skytrack.filters.registry import build_filter
from skytrack.models.converted import ConvertedPositionModel
from skytrack.models.motion import constant_velocity, singer

MOTIONS = {
    "cv2": lambda: constant_velocity(2, 1.0),
    "cv3": lambda: constant_velocity(3, 1.0),
    "singer3": lambda: singer(3, tau=20.0, sigma_a=3.0, discretization="exact"),
}
CASES = (("kalman-adaptive", "cv2"), ("kalman-adaptive", "cv3"), ("kalman-adaptive", "singer3"),
         ("adaptive-input-estimation", "singer3"))
RULES = {
    "literal": {"weighting": "fading", "prior_scans": 0, "gate_correction": False},
    "fading": {"weighting": "fading"},
    "information": {},
}
AXIS_SIGMA = (100.0, 30.0, 3.0)
TEST_SEED = 20240605


def sqrt_psd(Q):
    w, U = np.linalg.eigh(Q)
    return U * np.sqrt(np.clip(w, 0.0, None))[None, :]


def matched_nees(kind, motion_name, options, runs=200, steps=50, dt_s=2.0, seed=TEST_SEED, sigma_r=(30.0, 80.0),
                 recorder=None):
    """Per-scan NEES (mean over rows) of ``kind`` on its matched model: the conformance ``check_nees``
    draws (run r from ``SeedSequence(seed).spawn(runs)[r]``: start error, process noise, plot noise, R)."""
    motion = MOTIONS[motion_name]()
    filt = build_filter(kind, motion, compiled=False, **options)
    if recorder is not None:
        filt.recorder = recorder
    sim = getattr(filt, "matched_motion", None) or motion
    n, ndim, order = motion.dim, motion.ndim, motion.order
    pos = motion.position_index
    F = sim.F_batch(np.array([dt_s]))[0]
    Qs = sqrt_psd(sim.Q_batch(np.array([dt_s]))[0])
    H = np.zeros((ndim, n))
    H[np.arange(ndim), pos] = 1.0
    sigma0 = np.tile(AXIS_SIGMA[:order], ndim)
    e0, w, v, R = [], [], [], []
    for g in (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(runs)):
        e0.append(g.standard_normal(n))
        w.append(g.standard_normal((steps, n)))
        v.append(g.standard_normal((steps, ndim)))
        R.append(np.diag(g.uniform(*sigma_r, ndim) ** 2))
    e0, w, v, R = map(np.array, (e0, w, v, R))
    Rs = np.linalg.cholesky(R)
    xhat = np.zeros((runs, n))
    xhat[:, pos + 1] = 150.0
    truth = xhat + e0 * sigma0
    state = filt.initiate(xhat, np.broadcast_to(np.diag(sigma0**2), (runs, n, n)).copy())
    model = ConvertedPositionModel(ndim, order)
    nees = []
    for k in range(steps):
        truth = truth @ F.T + w[:, k] @ Qs.T
        z = truth @ H.T + np.einsum("kij,kj->ki", Rs, v[:, k])
        pred = filt.predict(state, np.full(runs, dt_s))
        state, _ = filt.update(pred, z, filt.innovate(pred, z, model, {"R": R}))
        est = state.estimate()
        e = truth - est.x
        nees.append(np.mean(np.einsum("ki,ki->k", e, np.linalg.solve(est.P, e[..., None])[..., 0])))
    return np.array(nees), n


def band(n, runs):
    return stats.chi2.ppf([0.025, 0.975], runs * n) / runs


def fmt(value, n, runs):
    lo, hi = band(n, runs)
    return f"{value:.2f}" + ("" if lo <= value <= hi else " (out)")


def q_sample_mean(weighting, r_pinned=False):
    """Mean and standard error of the q samples (table 6)."""
    recorder = ListRecorder()
    pinned = {"r_lo": 1.0, "r_hi": 1.0} if r_pinned else {}
    matched_nees("kalman-adaptive", "singer3", {"weighting": weighting, "q_lo": 1.0, "q_hi": 1.0, **pinned}, runs=400,
                 steps=60, seed=41, recorder=recorder)
    x = np.concatenate([values["q_sample"][values["adapted"]] for _, values in recorder.channel("adaptive")])
    return x.mean(), x.std() / np.sqrt(x.size)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    runs = args.runs
    console = Console()
    console.print(f"{cpu_model()}, {usable_cores()} cores, Python {platform.python_version()}, "
                  f"{dt.datetime.now().isoformat(timespec='minutes')}; {runs} rows")
    labels = [f"{'AKF' if kind == 'kalman-adaptive' else 'AIE'} {motion}" for kind, motion in CASES]

    table = Table(title="1. NEES on the matched model (conformance seed; 'out': outside the 95 % band)")
    for column in ("rule", *labels):
        table.add_column(column)
    table.add_row("band", *[f"{lo:.3f}-{hi:.3f}" for lo, hi in
                            (band(MOTIONS[m]().dim, runs) for _, m in CASES)])
    for rule, options in RULES.items():
        cells = []
        for kind, motion in CASES:
            nees, n = matched_nees(kind, motion, options, runs=runs)
            cells.append(fmt(nees.mean(), n, runs))
        table.add_row(rule, *cells)
    console.print(table)

    table = Table(title="2. fading vs information rule with one estimate pinned at the truth (kalman-adaptive)")
    for column in ("rule", "pinned", "cv2", "cv3", "singer3"):
        table.add_column(column)
    for rule in ("fading", "information"):
        for pinned, limits in (("q-hat", {"q_lo": 1.0, "q_hi": 1.0}), ("R-hat", {"r_lo": 1.0, "r_hi": 1.0}),
                               ("both", {"q_lo": 1.0, "q_hi": 1.0, "r_lo": 1.0, "r_hi": 1.0})):
            cells = []
            for motion in ("cv2", "cv3", "singer3"):
                nees, n = matched_nees("kalman-adaptive", motion, {**RULES[rule], **limits}, runs=runs)
                cells.append(fmt(nees.mean(), n, runs))
            table.add_row(rule, pinned, *cells)
    console.print(table)

    table = Table(title=f"3. information rule over {args.seeds} seeds (conformance seed first)")
    for column in ("case", "mean", "min", "max", "in band"):
        table.add_column(column)
    seeds = [TEST_SEED, *range(1, args.seeds)]
    for (kind, motion), label in zip(CASES, labels):
        values = []
        for seed in seeds:
            nees, n = matched_nees(kind, motion, {}, runs=runs, seed=seed)
            values.append(nees.mean())
        lo, hi = band(n, runs)
        values = np.array(values)
        table.add_row(label, f"{values.mean():.3f}", f"{values.min():.3f}", f"{values.max():.3f}",
                      f"{int(np.sum((values >= lo) & (values <= hi)))}/{len(values)}")
    console.print(table)

    table = Table(title="4. scans 101-200 of a 200-scan run, and 5. sigma_r 3-8 m (50 scans)")
    for column in ("rule", *[f"{label}: 101-200" for label in labels[2:]], *[f"{label}: 3-8 m" for label in labels]):
        table.add_column(column)
    for rule, options in RULES.items():
        cells = []
        for kind, motion in CASES[2:]:
            nees, n = matched_nees(kind, motion, options, runs=runs, steps=200)
            cells.append(f"{nees[100:].mean():.2f}")
        for kind, motion in CASES:
            nees, n = matched_nees(kind, motion, options, runs=runs, sigma_r=(3.0, 8.0))
            cells.append(fmt(nees.mean(), n, runs))
        table.add_row(rule, *cells)
    console.print(table)

    table = Table(title="6. q sample with q-hat at the truth (q = 1) and R-hat adapting, singer3, 400 x 60")
    for column in ("rule", "mean", "standard error"):
        table.add_column(column)
    for rule, pinned in (("fading", False), ("information", False), ("information, R-hat at the truth", True)):
        mean, error = q_sample_mean(rule.split(",")[0], pinned)
        table.add_row(rule, f"{mean:.2f}", f"{error:.2f}")
    console.print(table)

    table = Table(title="7. mis-specified start, CV, T = 1 s, sigma_r = 50 m, q = 1, 100 rows: mean (median) at scan 60 / 200")
    for column in ("rule", "R-hat_0, q0", "R-hat / R", "q-hat"):
        table.add_column(column)
    for rule in ("fading", "information"):
        for r0_scale, q0 in ((4.0, 25.0), (0.25, 1.0)):
            ratio, q_hat = start_history(RULES[rule], r0_scale, q0)
            cells = [" / ".join(f"{np.mean(h[k]):.3g} ({np.median(h[k]):.3g})" for k in (59, 199)) for h in (ratio, q_hat)]
            table.add_row(rule, f"{r0_scale:g} R, {q0:g}", *cells)
    console.print(table)


def start_history(options, r0_scale, q0, runs=100, steps=200):
    """R-hat_ii / R_ii (all axes) and q-hat per scan of kalman-adaptive on cv3 with a mis-specified start
    (table 7; study E6's start is R-hat_0 = 4 R, q0 = 25)."""
    recorder = ListRecorder()
    matched_nees("kalman-adaptive", "cv3", {**options, "r0_scale": r0_scale, "q0": q0}, runs=runs, steps=steps, dt_s=1.0,
                 seed=43, sigma_r=(50.0, 50.0 + 1e-9), recorder=recorder)
    events = recorder.channel("adaptive")
    ratio = np.stack([np.diagonal(values["R_hat"], axis1=-2, axis2=-1) for _, values in events]) / 50.0**2
    return ratio.reshape(len(events), -1), np.stack([values["q_hat"] for _, values in events])


if __name__ == "__main__":
    main()

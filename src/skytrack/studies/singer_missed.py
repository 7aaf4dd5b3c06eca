"""The accuracy study of spec 000 §6 (E1-E6): Singer filtering and extrapolation with missed detections.

Protocol of one run (the paper's A1-A3): gamma(0) = P+ of the P_D = 1 steady state (R12),
or the paper's start diag(sigma^2, sigma_v^2, sigma_a^2) (A0); for n = 1..N,
e-gamma(n) = F gamma(n-1) F^T + Q (Theorem 2), draw u_n ~ U(0, 1), the scan is detected iff
u_n < P_D, gamma(n) = update(e-gamma(n)) if detected else e-gamma(n) (Theorem 1 with the
flag phi of M4-M8).  The relative accuracies are

    FS11 = sqrt(mean_n gamma_11(n)) / sigma,   FES11 = sqrt(mean_n e-gamma_11(n)) / sigma   (A3).

The covariance recursion needs no trajectory, so all (sigma, P_D, run) cells of a variant
are one batch of :func:`skytrack.filters.spec000.covariance_recursion` (R15).

Seeding: run r of every Monte Carlo loop here draws from its own generator seeded with
``np.random.SeedSequence(seed).spawn(runs)[r]`` (:func:`run_generators`), so a run's
result does not depend on how many runs there are or how they are batched or distributed.
Run r uses the same stream in every cell (common random numbers): the uniforms u[run, n]
are shared by every sigma, P_D, variant and discretisation, so a cell's result does not
depend on the rest of the grid, and the per-run detection sets are nested in P_D, so
FS11/FES11 decrease monotonically in P_D run by run.

Also here: the E3 Kalman check, the E6 inverse read-off of the minimal P_D, the two
figures (Fig. 1 against P_D, Fig. 2 against sigma) and the E5 Monte Carlo consistency
check.  E5 takes the truth simulator as an argument (the CLI passes
``skytrack.sim.singer_truth.simulate_singer_1d``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.filters.spec000 import SingerFilterBank1D, covariance_recursion, steady_state
from skytrack.models.motion import SingerAxisModel

#: CSV columns of ``singer_missed.csv`` (spec 000 §6), in this order
CSV_COLUMNS = (
    "discretization", "variant", "sigma_m", "pd", "scans", "runs", "seed",
    "fs11_mean", "fs11_sd", "fes11_mean", "fes11_sd", "fs11_ss", "fes11_ss",
)
CSV_NAME = "singer_missed.csv"
FIG1_NAME = "singer_missed_vs_pd.png"
FIG2_NAME = "singer_missed_vs_sigma.png"
VARIANTS = ("pos", "posvel")
STARTS = ("steady", "paper-init")
#: E3 tolerance: at P_D = 1 from the steady state every gamma(n) equals P+
KALMAN_CHECK_TOLERANCE = 1e-9


@dataclass(frozen=True)
class StudyConfig:
    """Options of ``skytrack study singer-missed`` (§6), SI units."""

    dt: float = 10.0
    tau: float = 60.0
    sigma_a: float = 1.0
    sigma_v: float = 5.0
    sigmas: tuple[float, ...] = (30.0, 100.0, 200.0, 300.0, 500.0, 1000.0, 3000.0)
    pds: tuple[float, ...] = (0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0)
    variants: tuple[str, ...] = VARIANTS
    discretization: str = "paper"
    scans: int = 1000
    runs: int = 1
    seed: int = 0
    start: str = "steady"
    fig1_sigma: float = 100.0
    fig2_pds: tuple[float, ...] = (1.0, 0.9, 0.7)
    update_form: str = "joseph"

    def __post_init__(self):
        for name in ("dt", "tau", "sigma_v"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"--{name.replace('_', '-')} must be finite and > 0, got {value}")
        if not (math.isfinite(self.sigma_a) and self.sigma_a > 0):
            raise ValueError(f"--sigma-a must be finite and > 0, got {self.sigma_a}")
        _check_values("--sigma", self.sigmas, lambda s: math.isfinite(s) and s > 0, "finite and > 0")
        _check_values("--pd", self.pds, lambda p: 0.0 <= p <= 1.0, "in [0, 1]")
        _check_values("--fig2-pd", self.fig2_pds, lambda p: 0.0 <= p <= 1.0, "in [0, 1]")
        if not (math.isfinite(self.fig1_sigma) and self.fig1_sigma > 0):
            raise ValueError(f"--fig1-sigma must be finite and > 0, got {self.fig1_sigma}")
        if not self.variants or any(v not in VARIANTS for v in self.variants) or len(set(self.variants)) != len(self.variants):
            raise ValueError(f"--variants must be distinct values from {VARIANTS}, got {self.variants}")
        if self.discretization not in ("paper", "exact"):
            raise ValueError(f"--discretization must be 'paper' or 'exact', got {self.discretization!r}")
        if self.start not in STARTS:
            raise ValueError(f"--start must be one of {STARTS}, got {self.start!r}")
        for name in ("scans", "runs"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"--{name} must be a positive integer, got {value}")
        if int(self.seed) != self.seed or self.seed < 0:
            raise ValueError(f"--seed must be a non-negative integer, got {self.seed}")

    @property
    def model(self) -> SingerAxisModel:
        return SingerAxisModel(self.tau, self.sigma_a, self.discretization)

    @property
    def grid_sigmas(self) -> tuple[float, ...]:
        """The --sigma list plus --fig1-sigma (so that Fig. 1 can always be drawn)."""
        return tuple(sorted(set(self.sigmas) | {self.fig1_sigma}))

    @property
    def grid_pds(self) -> tuple[float, ...]:
        """The --pd list plus --fig2-pd."""
        return tuple(sorted(set(self.pds) | set(self.fig2_pds)))


def _check_values(option: str, values: Sequence[float], ok: Callable[[float], bool], what: str) -> None:
    if len(values) == 0:
        raise ValueError(f"{option} needs at least one value")
    bad = [v for v in values if not ok(v)]
    if bad:
        raise ValueError(f"{option} values must be {what}; got {bad}")


# --------------------------------------------------------------------------- covariance study


def run_seeds(seed: int, runs: int) -> list[np.random.SeedSequence]:
    """The seed of run r is ``np.random.SeedSequence(seed).spawn(runs)[r]`` (it does not depend on ``runs``)."""
    return np.random.SeedSequence(int(seed)).spawn(int(runs))


def run_generators(seed: int, runs: int) -> list[np.random.Generator]:
    """One fresh generator per run, seeded by :func:`run_seeds`."""
    return [np.random.default_rng(s) for s in run_seeds(seed, runs)]


def detection_uniforms(seed: int, runs: int, scans: int) -> np.ndarray:
    """u[run, n - 1] ~ U(0, 1) for scan n: the scan is detected iff u < P_D (A2); row r from run r's own generator."""
    u = np.empty((int(runs), int(scans)))
    for r, rng in enumerate(run_generators(seed, runs)):
        u[r] = rng.random(int(scans))
    return u


def initial_covariance(model: SingerAxisModel, variant: str, sigma: float, sigma_v: float, dt: float, start: str) -> np.ndarray:
    """gamma(0): P+ of the steady state (A1, R12) or the paper's diag(sigma^2, sigma_v^2, sigma_a^2) (A0)."""
    if start == "steady":
        return steady_state(model, variant, sigma=sigma, dt=dt, sigma_v=sigma_v).P_filt
    if start == "paper-init":
        return np.diag([sigma**2, sigma_v**2, model.sigma_a**2])
    raise ValueError(f"start must be one of {STARTS}, got {start!r}")


def relative_accuracy(
    model: SingerAxisModel,
    variant: str,
    *,
    sigma,
    sigma_v: float,
    dt: float,
    detection,
    n_scans: int,
    start: str = "steady",
    update_form: str = "joseph",
) -> tuple[np.ndarray, np.ndarray]:
    """FS11 and FES11 (A3) of B runs along given detection patterns.

    ``sigma``: scalar or [B]; ``detection``: bool [N, B] or a callable n -> bool[B].
    """
    sig = np.atleast_1d(np.asarray(sigma, dtype=float))
    unique = {float(s): initial_covariance(model, variant, float(s), sigma_v, dt, start) for s in np.unique(sig)}
    P0 = np.stack([unique[float(s)] for s in sig])
    averages = covariance_recursion(
        model, variant, sigma=sig, sigma_v=sigma_v, dt=dt, P0=P0, detection=detection,
        n_scans=n_scans, update_form=update_form,
    )
    fs11 = np.sqrt(averages.filtered[:, 0]) / sig
    fes11 = np.sqrt(averages.predicted[:, 0]) / sig
    return fs11, fes11


def steady_state_accuracy(model: SingerAxisModel, variant: str, sigma: float, sigma_v: float, dt: float) -> tuple[float, float]:
    """(fs11_ss, fes11_ss) = (sqrt(P+_11), sqrt(P-_11)) / sigma at P_D = 1 (TV8)."""
    P_pred, P_filt = steady_state(model, variant, sigma=sigma, dt=dt, sigma_v=sigma_v)
    return math.sqrt(P_filt[0, 0]) / sigma, math.sqrt(P_pred[0, 0]) / sigma


@dataclass(frozen=True)
class AccuracyTask:
    """One task of :func:`run_study`: one variant over every (sigma, P_D) cell for a batch of runs.

    ``run_seeds`` are the batch's children of ``SeedSequence(seed).spawn(runs)`` (issue 11 item 6)."""

    config: StudyConfig
    variant: str
    run_seeds: tuple


def accuracy_task(task: AccuracyTask) -> tuple[np.ndarray, np.ndarray]:
    """FS11 and FES11 ``[sigma, P_D, run]`` of the task's runs (pure: the task's seeds in, numbers out)."""
    config = task.config
    sigmas = np.array(config.grid_sigmas)
    pds = np.array(config.grid_pds)
    u = np.stack([np.random.default_rng(s).random(int(config.scans)) for s in task.run_seeds])
    n_s, n_p, n_r = len(sigmas), len(pds), len(task.run_seeds)

    def detected_at(n: int) -> np.ndarray:
        by_pd = u[:, n - 1][None, :] < pds[:, None]  # [P_D, run]
        return np.broadcast_to(by_pd, (n_s, n_p, n_r)).reshape(-1)

    fs11, fes11 = relative_accuracy(
        config.model, task.variant, sigma=np.repeat(sigmas, n_p * n_r), sigma_v=config.sigma_v, dt=config.dt,
        detection=detected_at, n_scans=config.scans, start=config.start, update_form=config.update_form,
    )
    return fs11.reshape(n_s, n_p, n_r), fes11.reshape(n_s, n_p, n_r)


def accuracy_tasks(config: StudyConfig) -> list[AccuracyTask]:
    """The tasks of :func:`run_study`: per variant, the runs cut into fixed batches of ``RUNS_PER_TASK``."""
    from skytrack.studies.parallel import batches

    seeds = run_seeds(config.seed, config.runs)
    return [AccuracyTask(config, variant, tuple(seeds[r] for r in batch))
            for variant in config.variants for batch in batches(config.runs)]


def run_study(config: StudyConfig, executor=None, progress: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """E1/E2/E4 table with the CSV columns of §6, one row per (variant, sigma, P_D), sorted.

    The runs are batched in :func:`accuracy_tasks` and mapped over ``executor`` (any
    ``concurrent.futures`` executor, ``None``: in this process); the numbers do not depend on it."""
    from skytrack.studies.parallel import map_tasks

    model = config.model
    sigmas = np.array(config.grid_sigmas)
    pds = np.array(config.grid_pds)
    n_s, n_p, n_r = len(sigmas), len(pds), config.runs
    tasks = accuracy_tasks(config)
    results = map_tasks(accuracy_task, tasks, executor, progress)
    frames = []
    for variant in config.variants:
        mine = [result for task, result in zip(tasks, results) if task.variant == variant]
        fs11 = np.concatenate([r[0] for r in mine], axis=-1)
        fes11 = np.concatenate([r[1] for r in mine], axis=-1)
        ddof_sd = (lambda a: a.std(axis=-1, ddof=1)) if n_r > 1 else (lambda a: np.full(a.shape[:-1], np.nan))
        ss = np.array([steady_state_accuracy(model, variant, s, config.sigma_v, config.dt) for s in sigmas])
        frames.append(pd.DataFrame({
            "discretization": config.discretization,
            "variant": variant,
            "sigma_m": np.repeat(sigmas, n_p),
            "pd": np.tile(pds, n_s),
            "scans": config.scans,
            "runs": n_r,
            "seed": config.seed,
            "fs11_mean": fs11.mean(axis=-1).ravel(),
            "fs11_sd": ddof_sd(fs11).ravel(),
            "fes11_mean": fes11.mean(axis=-1).ravel(),
            "fes11_sd": ddof_sd(fes11).ravel(),
            "fs11_ss": np.repeat(ss[:, 0], n_p),
            "fes11_ss": np.repeat(ss[:, 1], n_p),
        }))
    table = pd.concat(frames, ignore_index=True)
    return table.loc[:, list(CSV_COLUMNS)]


# --------------------------------------------------------------------------- E3, E6


def kalman_check(table: pd.DataFrame, tolerance: float = KALMAN_CHECK_TOLERANCE) -> pd.DataFrame:
    """E3: rows with P_D = 1 and their deviations |FS11 - fs11_ss|, |FES11 - fes11_ss| (valid for a steady start)."""
    rows = table[table["pd"] == 1.0].copy()
    rows["fs11_dev"] = (rows["fs11_mean"] - rows["fs11_ss"]).abs()
    rows["fes11_dev"] = (rows["fes11_mean"] - rows["fes11_ss"]).abs()
    rows["ok"] = (rows["fs11_dev"] <= tolerance) & (rows["fes11_dev"] <= tolerance)
    return rows[["discretization", "variant", "sigma_m", "fs11_mean", "fs11_ss", "fes11_mean", "fes11_ss", "fs11_dev", "fes11_dev", "ok"]]


def minimal_pd(table: pd.DataFrame, required: float, column: str = "fs11_mean") -> pd.DataFrame:
    """E6: per (discretization, variant, sigma) the smallest P_D with ``column`` <= ``required``.

    Linear interpolation along the P_D grid between the last grid point above the
    requirement and the next one at or below it (the curves decrease in P_D).  NaN when even
    the largest P_D of the grid misses the requirement; the smallest grid P_D when it
    already meets it there (the grid does not say more; ``at_grid_start`` is then True).
    """
    if column not in ("fs11_mean", "fes11_mean"):
        raise ValueError(f"column must be fs11_mean or fes11_mean, got {column!r}")
    if not (math.isfinite(required) and required > 0):
        raise ValueError(f"required accuracy must be finite and > 0, got {required}")
    out = []
    for (disc, variant, sigma), group in table.groupby(["discretization", "variant", "sigma_m"], sort=True):
        group = group.sort_values("pd")
        p = group["pd"].to_numpy()
        f = group[column].to_numpy()
        meets = np.flatnonzero(f <= required)
        at_grid_start = bool(meets.size and meets[0] == 0)
        if meets.size == 0:
            value = math.nan
        elif at_grid_start:
            value = float(p[0])
        else:
            i = meets[0]
            p0, p1, f0, f1 = p[i - 1], p[i], f[i - 1], f[i]
            value = float(p0 + (f0 - required) * (p1 - p0) / (f0 - f1))
        out.append({"discretization": disc, "variant": variant, "sigma_m": sigma, "required": required,
                    "column": column, "pd_min": value, "at_grid_start": at_grid_start})
    return pd.DataFrame(out)


# --------------------------------------------------------------------------- figures


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_LINESTYLE = {"pos": "-", "posvel": "--"}


def plot_vs_pd(table: pd.DataFrame, sigma: float, path: Path) -> Path:
    """Fig. 1: FS11 and FES11 against P_D at one sigma; solid = pos, dashed = posvel."""
    plt = _figure()
    rows = table[np.isclose(table["sigma_m"], sigma)]
    if rows.empty:
        raise ValueError(f"no study rows at sigma = {sigma} m for Fig. 1")
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for variant, group in rows.groupby("variant"):
        group = group.sort_values("pd")
        ls = _LINESTYLE.get(variant, ":")
        ax.plot(group["pd"], group["fs11_mean"], ls, color="tab:blue", marker="o", label=f"FS11 {variant}")
        ax.plot(group["pd"], group["fes11_mean"], ls, color="tab:red", marker="s", label=f"FES11 {variant}")
    disc = ", ".join(sorted(rows["discretization"].unique()))
    ax.set_xlabel("probability of detection $P_D$")
    ax.set_ylabel("relative accuracy (RMS / $\\sigma$)")
    ax.set_title(f"Filtering / extrapolation accuracy vs $P_D$ ($\\sigma$ = {sigma:g} m, {disc})")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_vs_sigma(table: pd.DataFrame, pds: Sequence[float], path: Path) -> Path:
    """Fig. 2: FS11 (left) and FES11 (right) against sigma (log axis) for each P_D; solid = pos, dashed = posvel."""
    plt = _figure()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    drawn = 0
    for k, pd_value in enumerate(pds):
        rows = table[np.isclose(table["pd"], pd_value)]
        for variant, group in rows.groupby("variant"):
            group = group.sort_values("sigma_m")
            ls = _LINESTYLE.get(variant, ":")
            colour = colours[k % len(colours)]
            for ax, column in zip(axes, ("fs11_mean", "fes11_mean")):
                ax.plot(group["sigma_m"], group[column], ls, color=colour, marker="o", label=f"$P_D$={pd_value:g} {variant}")
            drawn += 1
    if drawn == 0:
        plt.close(fig)
        raise ValueError(f"no study rows at P_D in {list(pds)} for Fig. 2")
    for ax, name in zip(axes, ("FS11", "FES11")):
        ax.set_xscale("log")
        ax.set_xlabel("measurement error st. dev. $\\sigma$ [m]")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize="small")
    fig.suptitle("Filtering (FS11) and extrapolation (FES11) accuracy vs $\\sigma$")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_outputs(table: pd.DataFrame, config: StudyConfig, out_dir: Path) -> dict[str, Path]:
    """Write the CSV and the two PNG figures of §6 into ``out_dir`` (created if needed)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / CSV_NAME
    table.loc[:, list(CSV_COLUMNS)].to_csv(csv_path, index=False, float_format="%.10g")
    return {
        "csv": csv_path,
        "fig1": plot_vs_pd(table, config.fig1_sigma, out_dir / FIG1_NAME),
        "fig2": plot_vs_sigma(table, config.fig2_pds, out_dir / FIG2_NAME),
    }


# --------------------------------------------------------------------------- E5 / R14 consistency


@dataclass(frozen=True)
class ConsistencyStats:
    """Empirical mean-square errors next to the filter's mean variances (R14, E5).

    ``mse``/``variance`` hold x, v, a of the filtered estimate and x of the extrapolation:
    keys ``"x"``, ``"v"``, ``"a"``, ``"x_pred"``.
    """

    mse: dict[str, float]
    variance: dict[str, float]
    samples: int

    @property
    def ratios(self) -> dict[str, float]:
        return {k: self.mse[k] / self.variance[k] for k in self.mse}


def filter_consistency(
    model: SingerAxisModel,
    variant: str,
    *,
    sigma: float,
    sigma_v: float | None,
    dt: float,
    truth: np.ndarray,
    measurements: np.ndarray,
    detected: np.ndarray,
    m0,
    P0,
    burn_in: int = 0,
    update_form: str = "joseph",
) -> ConsistencyStats:
    """Run a bank of filters over simulated runs and compare errors with the filter's covariances.

    ``truth[runs, N+1, 3]``, ``measurements[runs, N+1, k]``, ``detected[runs, N+1]`` (scan 0
    is the start: the filter begins at (m0, P0), the prior the truth was drawn from).
    Statistics are taken over runs and scans n > ``burn_in``.
    """
    truth = np.asarray(truth, dtype=float)
    runs, n_total, _ = truth.shape
    if not (0 <= burn_in < n_total - 1):
        raise ValueError(f"burn_in must be in [0, {n_total - 2}], got {burn_in}")
    bank = SingerFilterBank1D(model, sigma, variant, sigma_v, n_tracks=runs, update_form=update_form)
    bank.set_state(m0, P0)
    # scan-major copies: one contiguous [runs, ...] slab per scan
    truth_by_scan = np.ascontiguousarray(truth.transpose(1, 0, 2))
    meas_by_scan = np.ascontiguousarray(np.asarray(measurements, dtype=float).transpose(1, 0, 2))
    det_by_scan = np.ascontiguousarray(np.asarray(detected, dtype=bool).T)
    sq = np.zeros(4)  # x, v, a, x_pred
    var = np.zeros(4)
    for n in range(1, n_total):
        bank.predict(dt)
        if n > burn_in:
            err_pred = bank.m[:, 0] - truth_by_scan[n, :, 0]
            sq[3] += err_pred @ err_pred
            var[3] += bank.P[:, 0, 0].sum()
        bank.update(meas_by_scan[n], det_by_scan[n])
        if n > burn_in:
            err = bank.m - truth_by_scan[n]
            sq[:3] += np.einsum("ri,ri->i", err, err)
            var[:3] += np.einsum("rii->i", bank.P)
    samples = runs * (n_total - 1 - burn_in)
    keys = ("x", "v", "a", "x_pred")
    return ConsistencyStats({k: float(sq[i] / samples) for i, k in enumerate(keys)},
                            {k: float(var[i] / samples) for i, k in enumerate(keys)}, samples)


@dataclass(frozen=True)
class ConsistencyTask:
    """One E5 cell: a (variant, sigma, P_D) with its runs' seeds and the truth simulator (a module-level function)."""

    config: StudyConfig
    simulate: Callable[..., object]
    variant: str
    sigma: float
    p_d: float
    run_seeds: tuple


def consistency_task(task: ConsistencyTask) -> dict:
    """The E5 row of one cell (pure: the cell and its seeds in, a dict of numbers out)."""
    config, variant, sigma, p_d = task.config, task.variant, task.sigma, task.p_d
    model = config.model
    mc_runs = len(task.run_seeds)
    P0 = initial_covariance(model, variant, sigma, config.sigma_v, config.dt, config.start)
    rng = [np.random.default_rng(s) for s in task.run_seeds]
    scenario = task.simulate(
        model, dt=config.dt, n_scans=config.scans, runs=mc_runs, sigma=sigma, p_detection=p_d,
        rng=rng, measurement=variant, sigma_v=config.sigma_v, m0=np.zeros(3), P0=P0,
    )
    stats = filter_consistency(
        model, variant, sigma=sigma, sigma_v=config.sigma_v, dt=config.dt, truth=scenario.truth,
        measurements=scenario.measurements, detected=scenario.detected, m0=np.zeros(3), P0=P0,
        update_form=config.update_form,
    )
    rms_f, rms_p = math.sqrt(stats.mse["x"]), math.sqrt(stats.mse["x_pred"])
    sd_f, sd_p = math.sqrt(stats.variance["x"]), math.sqrt(stats.variance["x_pred"])
    return {
        "discretization": config.discretization, "variant": variant, "sigma_m": sigma, "pd": p_d,
        "mc_runs": mc_runs, "rms_filtered_m": rms_f, "sqrt_mean_gamma11_m": sd_f,
        "ratio_filtered": rms_f / sd_f, "rms_extrapolated_m": rms_p, "sqrt_mean_egamma11_m": sd_p,
        "ratio_extrapolated": rms_p / sd_p,
    }


def monte_carlo_consistency(
    config: StudyConfig,
    simulate: Callable[..., object],
    mc_runs: int,
    on_cell_done: Callable[[], None] | None = None,
    executor=None,
    progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """E5: simulate truth and reports (R14) for every (variant, sigma, P_D) cell and compare
    the empirical RMS filtered / extrapolated position errors with sqrt(mean gamma_11) and
    sqrt(mean e-gamma_11).

    ``simulate`` has the signature of ``skytrack.sim.singer_truth.simulate_singer_1d`` and
    returns an object with ``truth``, ``measurements`` and ``detected``; it is given one
    generator per run (``rng=[...]``), run r's seeded with ``SeedSequence(seed).spawn(mc_runs)[r]``
    afresh in every cell, so results depend neither on the rest of the grid nor on how the
    runs are batched.  Runs start from (0, gamma(0)) with the truth drawn from the same law.
    Every cell is one task (:class:`ConsistencyTask`) mapped over ``executor`` (``None``: in this
    process; a process pool or Dask needs a module-level ``simulate``); ``on_cell_done()`` and
    ``progress(done, total)`` follow the cells as they complete.
    """
    from skytrack.studies.parallel import map_tasks

    if int(mc_runs) != mc_runs or mc_runs < 2:
        raise ValueError(f"--mc-runs must be an integer >= 2, got {mc_runs}")
    seeds = tuple(run_seeds(config.seed, int(mc_runs)))
    tasks = [ConsistencyTask(config, simulate, variant, sigma, p_d, seeds)
             for variant in VARIANTS if variant in config.variants
             for sigma in config.grid_sigmas for p_d in config.grid_pds]

    def report(done: int, total: int) -> None:
        if on_cell_done is not None and done > 0:
            on_cell_done()
        if progress is not None:
            progress(done, total)

    return pd.DataFrame(map_tasks(consistency_task, tasks, executor, report))


def monte_carlo_cells(config: StudyConfig) -> int:
    """Number of (variant, sigma, P_D) cells :func:`monte_carlo_consistency` simulates (for progress bars)."""
    return len(config.variants) * len(config.grid_sigmas) * len(config.grid_pds)

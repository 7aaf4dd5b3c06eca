"""``skytrack study`` sub-commands; here ``singer-missed``, the accuracy study of spec 000 §6 (R15).

The command only parses options, calls :mod:`skytrack.studies.singer_missed` and prints:
the FS11/FES11 table (E1/E2/E4), the E3 Kalman check at P_D = 1 (a failure exits with
code 1), the E6 minimal-P_D read-off for ``--require-fs11``, and with ``--monte-carlo``
the E5 consistency table (simulated with :mod:`skytrack.sim.singer_truth`, rich progress bar).
Outputs: ``singer_missed.csv``, ``singer_missed_vs_pd.png``, ``singer_missed_vs_sigma.png``
(and ``singer_missed_mc.csv`` with ``--monte-carlo``) in ``--out``.  ``--workers``/``--scheduler`` choose
where the batches of runs and the E5 cells run (issue 11 item 6); the numbers do not depend on it.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from skytrack.cli.study_output import SchedulerOption, WorkersOption, study_executor
from skytrack.cli.study_fuzzy import register_fuzzy_studies
from skytrack.cli.study_ident_mc import register_mc_studies
from skytrack.cli.study_ident_potential import register_potential_studies
from skytrack.cli.study_maneuver import register_maneuver_studies
from skytrack.cli.study_adaptive_numerics import register_adaptive_numerics_studies
from skytrack.cli.study_identifiability import register_identifiability_studies
from skytrack.cli.study_turn_rate import register_turn_rate_studies

study_app = typer.Typer(help="Reproduce the studies of the papers in shared/specs.", no_args_is_help=True)
register_maneuver_studies(study_app)  # spec 004 §6: skytrack study kf-gains, ...
register_fuzzy_studies(study_app)  # spec 003 §6: skytrack study fuzzy-fig2, fuzzy-regions, fuzzy-gate, ...
register_potential_studies(study_app)  # spec 001 §6 E1-E4: skytrack study ident-potential, ident-np-design, ident-elliptic
register_mc_studies(study_app)  # spec 001 §6 E5-E9: skytrack study ident-sequential-mc, ..., ident-many-to-many
register_identifiability_studies(study_app)  # spec 002 §6 E1-E2: skytrack study ident-example, ident-radar
register_turn_rate_studies(study_app)  # spec 002 §6 E3-E4: skytrack study turn-rate-adaptive [--q-dep 0]
register_adaptive_numerics_studies(study_app)  # spec 002 §6 E5-E7: gain-conditioning, poor-experiment, vw-estimator

#: E5: for P_D >= this, the Monte Carlo ratios must lie within 1 +- MC_BAND
MC_PD_CHECKED = 0.7
MC_BAND = 0.03
MC_CSV_NAME = "singer_missed_mc.csv"


def _float_list(option: str, text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise typer.BadParameter(f"{option} expects comma-separated numbers, got {text!r}") from None
    if not values:
        raise typer.BadParameter(f"{option} needs at least one value")
    return values


def _str_list(text: str) -> tuple[str, ...]:
    return tuple(part.strip() for part in text.split(",") if part.strip())


def _fmt(value: float, digits: int = 4) -> str:
    return "–" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}g}"


def _results_table(table, title: str) -> Table:
    out = Table(title=title)
    for name in ("variant", "σ [m]", "P_D", "FS11", "sd", "FES11", "sd", "FS11 ss", "FES11 ss"):
        out.add_column(name, justify="right")
    for row in table.itertuples(index=False):
        out.add_row(row.variant, f"{row.sigma_m:g}", f"{row.pd:g}", _fmt(row.fs11_mean), _fmt(row.fs11_sd, 2),
                    _fmt(row.fes11_mean), _fmt(row.fes11_sd, 2), _fmt(row.fs11_ss, 8), _fmt(row.fes11_ss, 8))
    return out


@study_app.command("singer-missed")
def singer_missed(
    dt: float = typer.Option(10.0, "--dt", help="scan period Δ [s]"),
    tau: float = typer.Option(60.0, "--tau", help="Singer manoeuvre time constant τ [s]"),
    sigma_a: float = typer.Option(1.0, "--sigma-a", help="acceleration st. dev. σ_a [m/s²]"),
    sigma_v: float = typer.Option(5.0, "--sigma-v", help="velocity measurement st. dev. σ_v [m/s] (also σ_v0 of --start paper-init)"),
    sigma: str = typer.Option("30,100,200,300,500,1000,3000", "--sigma", help="position measurement st. devs σ [m]"),
    pd: str = typer.Option("0.5,0.6,0.7,0.8,0.9,0.95,1.0", "--pd", help="probabilities of detection"),
    variants: str = typer.Option("pos,posvel", "--variants", help="measurement variants: pos, posvel"),
    discretization: str = typer.Option("paper", "--discretization", help="paper (K6) or exact (X1–X2)"),
    scans: int = typer.Option(1000, "--scans", help="scans per run"),
    runs: int = typer.Option(1, "--runs", help="independent runs (mean and sd are reported)"),
    seed: int = typer.Option(0, "--seed", help="random seed"),
    start: str = typer.Option("steady", "--start", help="steady (P+ of the DARE) or paper-init (A0)"),
    fig1_sigma: float = typer.Option(100.0, "--fig1-sigma", help="σ [m] of Fig. 1 (accuracy vs P_D)"),
    fig2_pd: str = typer.Option("1.0,0.9,0.7", "--fig2-pd", help="P_D values of Fig. 2 (accuracy vs σ)"),
    out: Path = typer.Option(Path("singer_missed"), "--out", help="output directory"),
    monte_carlo: bool = typer.Option(False, "--monte-carlo", help="E5: simulate truth and check consistency"),
    mc_runs: int = typer.Option(2000, "--mc-runs", help="Monte Carlo runs per cell"),
    require_fs11: float | None = typer.Option(None, "--require-fs11", help="E6: print the minimal P_D with FS11 ≤ this, per σ"),
    require_fes11: float | None = typer.Option(None, "--require-fes11", help="E6: the same for FES11"),
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Singer filtering / one-scan extrapolation accuracy with missed detections (spec 000 §6)."""
    from skytrack.studies import singer_missed as study  # the library is imported here: --help stays light

    console = Console()
    try:
        config = study.StudyConfig(
            dt=dt, tau=tau, sigma_a=sigma_a, sigma_v=sigma_v, sigmas=_float_list("--sigma", sigma),
            pds=_float_list("--pd", pd), variants=_str_list(variants), discretization=discretization,
            scans=scans, runs=runs, seed=seed, start=start, fig1_sigma=fig1_sigma,
            fig2_pds=_float_list("--fig2-pd", fig2_pd),
        )
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from None

    started = time.perf_counter()
    with study_executor(console, workers, scheduler) as executor:  # issue 11 item 6: runs in batches of tasks
        table = study.run_study(config, executor)
        if monte_carlo:
            mc = _monte_carlo_table(console, config, mc_runs, executor)
    paths = study.write_outputs(table, config, out)
    elapsed = time.perf_counter() - started
    console.print(_results_table(table, f"singer-missed: {config.discretization}, {config.runs} run(s) × {config.scans} scans, seed {config.seed}"))
    console.print(f"study: {elapsed:.2f} s; wrote {paths['csv']}, {paths['fig1']}, {paths['fig2']}")

    failed = False
    if config.start == "steady" and 1.0 in config.grid_pds:
        check = study.kalman_check(table)
        kt = Table(title=f"E3 Kalman check (P_D = 1, tolerance {study.KALMAN_CHECK_TOLERANCE:g})")
        for name in ("variant", "σ [m]", "FS11", "fs11_ss", "FES11", "fes11_ss", "ok"):
            kt.add_column(name, justify="right")
        for row in check.itertuples(index=False):
            kt.add_row(row.variant, f"{row.sigma_m:g}", f"{row.fs11_mean:.8f}", f"{row.fs11_ss:.8f}",
                       f"{row.fes11_mean:.8f}", f"{row.fes11_ss:.8f}", "yes" if row.ok else "[red]NO[/red]")
        console.print(kt)
        failed |= not bool(check["ok"].all())

    for required, column in ((require_fs11, "fs11_mean"), (require_fes11, "fes11_mean")):
        if required is None:
            continue
        try:
            read_off = study.minimal_pd(table, required, column)
        except ValueError as exc:
            raise typer.BadParameter(str(exc)) from None
        name = column.split("_")[0].upper()
        rt = Table(title=f"E6 minimal P_D with {name} ≤ {required:g}")
        for col in ("variant", "σ [m]", "P_D min"):
            rt.add_column(col, justify="right")
        for row in read_off.itertuples(index=False):
            if math.isnan(row.pd_min):
                text = "not reached"
            else:
                text = f"≤ {row.pd_min:.4f}" if row.at_grid_start else f"{row.pd_min:.4f}"
            rt.add_row(row.variant, f"{row.sigma_m:g}", text)
        console.print(rt)

    if monte_carlo:
        failed |= _print_monte_carlo(console, mc, mc_runs, Path(out))
    if failed:
        console.print("[red]a consistency check failed[/red]")
        raise typer.Exit(code=1)


def _monte_carlo_table(console: Console, config, mc_runs: int, executor):
    """E5 with a progress bar, one task per cell on ``executor``."""
    from skytrack.studies import singer_missed as study
    from skytrack.sim.singer_truth import simulate_singer_1d

    columns = (TextColumn("Monte Carlo"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    try:
        with Progress(*columns, console=console, transient=False) as progress:
            task = progress.add_task("mc", total=study.monte_carlo_cells(config))
            return study.monte_carlo_consistency(config, simulate_singer_1d, mc_runs, executor=executor,
                                                 progress=lambda done, total: progress.update(task, completed=done))
    except ValueError as exc:
        raise typer.BadParameter(str(exc)) from None


def _print_monte_carlo(console: Console, mc, mc_runs: int, out: Path) -> bool:
    """Write and print the E5 table; returns True if a checked ratio is outside 1 ± MC_BAND."""
    mc.to_csv(out / MC_CSV_NAME, index=False, float_format="%.10g")
    checked = mc["pd"] >= MC_PD_CHECKED
    bad = checked & (((mc["ratio_filtered"] - 1).abs() > MC_BAND) | ((mc["ratio_extrapolated"] - 1).abs() > MC_BAND))
    mt = Table(title=f"E5 Monte Carlo consistency ({mc_runs} runs per cell; checked for P_D ≥ {MC_PD_CHECKED}: 1 ± {MC_BAND})")
    for name in ("variant", "σ [m]", "P_D", "RMS filt [m]", "√mean γ11", "ratio", "RMS extr [m]", "√mean eγ11", "ratio"):
        mt.add_column(name, justify="right")
    for row, is_bad in zip(mc.itertuples(index=False), bad):
        mark = "[red]" if is_bad else ""
        mt.add_row(row.variant, f"{row.sigma_m:g}", f"{row.pd:g}", f"{row.rms_filtered_m:.2f}", f"{row.sqrt_mean_gamma11_m:.2f}",
                   f"{mark}{row.ratio_filtered:.4f}", f"{row.rms_extrapolated_m:.2f}", f"{row.sqrt_mean_egamma11_m:.2f}",
                   f"{mark}{row.ratio_extrapolated:.4f}")
    console.print(mt)
    console.print(f"wrote {out / MC_CSV_NAME}")
    return bool(bad.any())

"""The ``skytrack`` command: simulate, track, evaluate, demo and the papers' studies.

Thin layer (DESIGN.md): parse options, call the library (:mod:`skytrack.app` holds the
pipelines), print with rich.  Every input problem ends in a one-line error naming the
file and the place (exit code 2), never in a traceback.

Start-up stays light: this module and the other ``cli`` modules import only typer and
rich at module level; the library (numpy, pandas, scipy, matplotlib behind it) is
imported inside the command functions, so ``skytrack --help`` answers at once.  Option
defaults that mirror :class:`~skytrack.tracker.TrackerConfig` come from
:mod:`skytrack.cli.defaults`.
"""

from __future__ import annotations

import functools
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.table import Table

from skytrack import __version__
from skytrack.cli import defaults
from skytrack.cli.identify import identify_app
from skytrack.cli.observability import observability_app
from skytrack.cli.serve import register_serve
from skytrack.cli.study import study_app
from skytrack.cli.track_many import register_track_many

app = typer.Typer(
    name="skytrack",
    help="Air-surveillance tracking: radar plots, SSR and ADS-B to an identified air picture.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(study_app, name="study")
app.add_typer(identify_app, name="identify")
app.add_typer(observability_app, name="observability")
register_serve(app)
register_track_many(app)  # issue 11 item 6: skytrack track-many FILES... [--workers N | --scheduler ADDRESS]

console = Console()
error_console = Console(stderr=True)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def reports_input_errors(command):
    """Turn input problems (bad files, bad options) into a one-line error and exit code 2."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        # skytrack.sim.ScenarioError is a ValueError: importing the simulator here to name it
        # would cost every command (``track`` too) a good part of a second
        try:
            return command(*args, **kwargs)
        except (ValueError, KeyError, FileNotFoundError) as exc:
            message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
            _fail(str(message))

    return wrapper


@contextmanager
def _progress():
    """A rich progress display on stderr; yields the library's ``progress(stage, completed, total)`` callback."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    display = Progress(
        TextColumn("[bold]{task.description:<12}"),
        BarColumn(),
        TextColumn("{task.percentage:>5.1f}%"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=error_console,
        transient=False,
    )
    tasks: dict[str, int] = {}

    def update(stage: str, completed: float, total: float | None) -> None:
        total = total if total is not None else completed  # unknown length (CSV): show what was read
        if stage not in tasks:
            tasks[stage] = display.add_task(stage, total=total)
        display.update(tasks[stage], completed=completed, total=total)

    with display:
        yield update


def _version(value: bool) -> None:
    if value:
        console.print(f"skytrack {__version__}")
        raise typer.Exit()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Input warnings (e.g. values that look like another unit) as one plain line."""
    error_console.print(f"[yellow]warning:[/] {message}", highlight=False, soft_wrap=True)


@app.callback()
def main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    """skytrack command line."""
    warnings.showwarning = _show_warning


# ---------------------------------------------------------------------------- simulate
@app.command()
@reports_input_errors
def simulate(
    scenario: Annotated[Optional[str], typer.Argument(help="Scenario YAML file, or the name of a bundled scenario (demo, two_radars, radar3d, crossing, recorded_switzerland, ...).")] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder for plots, truth and sensors.json (and adsb when the scenario has ADS-B or recorded traffic).")] = ...,
    scenario_option: Annotated[Optional[str], typer.Option("--scenario", help="The scenario, as an option (same as the argument).")] = None,
    trajectories: Annotated[Optional[str], typer.Option("--trajectories", help="Recorded state vectors flown as truth (Parquet, CSV or JSON lines of the traffic or OpenSky layout; or a bundled recording's name): replaces the scenario's recorded file.")] = None,
    start: Annotated[Optional[str], typer.Option("--start", help="Time 0 on the recording: ISO-8601 UTC (2018-08-01T11:20:00Z) or seconds after its first time stamp.")] = None,
    duration: Annotated[Optional[float], typer.Option("--duration", help="Simulated time span (s), replacing the scenario's duration_s.")] = None,
    seed: Annotated[Optional[int], typer.Option(help="Seed of the measurement noise (default: the scenario's).")] = None,
    fmt: Annotated[str, typer.Option("--format", help="parquet or csv tables, or asterix: plots.ast (CAT048 plots, CAT034 north markers, CAT021 ADS-B), truth.parquet, sensors.json with SAC/SIC.")] = "parquet",
) -> None:
    """Simulate a scenario and write plots, truth and sensors.json (FORMATS.md); a scenario with an adsb section or recorded traffic also gives ADS-B reports."""
    from skytrack.app.simulate import SIMULATION_FORMATS, run_simulation, write_simulation

    if fmt not in SIMULATION_FORMATS:
        _fail(f"--format must be parquet, csv or asterix, got {fmt!r}")
    if (scenario is None) == (scenario_option is None):
        _fail("give the scenario once: as the argument or as --scenario")
    if duration is not None and not duration > 0.0:
        _fail(f"--duration must be > 0, got {duration!r}")
    with _progress() as progress:
        result = run_simulation(scenario or scenario_option, seed, progress=progress, trajectories=trajectories,
                                start=start, duration=duration)
        paths = write_simulation(result, out, fmt, progress=progress)
    _print_simulation_summary(result, paths)


def _print_simulation_summary(result, paths: dict) -> None:
    plots = result.plots
    false_plots = int((plots["truth_id"] == "").sum()) if "truth_id" in plots.columns else 0
    table = Table(title=f"simulated scenario {result.scenario.name!r}", show_header=False)
    table.add_row("aircraft", str(result.truth["target_id"].nunique()))
    table.add_row("sensors", ", ".join(result.sensors.names))
    table.add_row("duration", f"{result.scenario.duration_s:.0f} s")
    table.add_row("plots", f"{len(plots)} ({false_plots} false)")
    if result.recorded is not None:
        recorded = result.recorded
        table.add_row("recorded window", f"{recorded.epoch_utc} + {result.scenario.duration_s:g} s: "
                                         f"{len(recorded.trajectories)} segments")
    if result.adsb is not None:
        table.add_row("ADS-B reports", str(len(result.adsb)))
    if result.adsb_aircraft is not None:
        aircraft = result.adsb_aircraft
        faults = aircraft.loc[aircraft["fault"].fillna("") != "", ["target_id", "fault"]]
        shown = ", ".join(f"{row.target_id} ({row.fault})" for row in faults.itertuples())
        table.add_row("ADS-B aircraft", f"{int(aircraft['equipped'].sum())} of {len(aircraft)} equipped"
                                        + (f"; faults: {shown}" if shown else ""))
    for name, path in paths.items():
        table.add_row(name, str(path))
    console.print(table)
    if result.recorded is not None:
        _print_cleaning(result.recorded.cleaning)


def _print_cleaning(cleaning) -> None:
    """The counts of :class:`skytrack.sim.cleaning.CleaningReport`, one row each."""
    table = Table(title="cleaning of the recording (whole file)", show_header=False)
    table.add_row("rows read", f"{cleaning.rows_read} ({cleaning.aircraft_read} aircraft)")
    table.add_row("rows out of time order (sorted)", str(cleaning.reordered))
    for step, count in cleaning.removed.items():
        table.add_row(f"removed: {step.replace('_', ' ')}", str(count))
    table.add_row("altitudes replaced (spikes)", str(cleaning.altitudes_replaced))
    table.add_row("gaps cut", str(cleaning.gaps))
    table.add_row("rows kept", f"{cleaning.rows_kept} in {cleaning.segments} segments of {cleaning.aircraft_kept} aircraft")
    console.print(table)


# ---------------------------------------------------------------------------- track
def _association_options(config, rule: str | None, mode: str | None, missing_iff: str | None):
    """``--association-rule``, ``--association-mode`` and ``--missing-iff`` over the configuration."""
    from skytrack.association.features import MISSING_IFF_RULES
    from skytrack.association.registry import SCORERS
    from skytrack.tracker.scan import ASSOCIATION_MODES

    for option, value, allowed in (("--association-rule", rule, tuple(SCORERS)),
                                   ("--association-mode", mode, ASSOCIATION_MODES),
                                   ("--missing-iff", missing_iff, MISSING_IFF_RULES)):
        if value is not None and value not in allowed:
            _fail(f"{option}: unknown {value!r}; choose one of {', '.join(allowed)}")
    given = {"association_rule": rule, "association_mode": mode, "missing_iff": missing_iff}
    return config.replace(**{name: value for name, value in given.items() if value is not None})


@app.command()
@reports_input_errors
def track(
    ctx: typer.Context,
    plots: Annotated[Path, typer.Argument(help="Plots table (.parquet or .csv, FORMATS.md layout) or an ASTERIX recording (.ast, .pcap: CAT048 plots, CAT034 north markers; sensors by sac/sic).")],
    sensors: Annotated[Path, typer.Option("--sensors", help="sensors.json describing the radars.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Tracks table to write (.parquet or .csv; .ast: ASTERIX CAT062 system tracks).")],
    model: Annotated[str, typer.Option(help="Motion model: cv or singer.")] = defaults.MODEL,
    q: Annotated[float, typer.Option("--q", help="CV white-noise acceleration PSD (m^2/s^3).")] = defaults.CV_Q,
    tau: Annotated[float, typer.Option("--tau", help="Singer manoeuvre time constant (s).")] = defaults.SINGER_TAU_S,
    sigma_a: Annotated[float, typer.Option("--sigma-a", help="Singer acceleration standard deviation (m/s^2).")] = defaults.SINGER_SIGMA_A,
    discretization: Annotated[str, typer.Option(help="Singer discretisation: exact or paper (spec 000).")] = defaults.DISCRETIZATION,
    manoeuvre_scale: Annotated[Optional[float], typer.Option(help="Process-noise factor while a track manoeuvres (1 = off; default 3000 for cv, off for singer).")] = None,
    p_gate: Annotated[float, typer.Option(help="Gate probability P_G (chi-square gate).")] = defaults.P_GATE,
    gate_threshold: Annotated[Optional[float], typer.Option(help="Gate threshold g (overrides --p-gate).")] = None,
    confirm: Annotated[str, typer.Option(help="M/N confirmation rule, e.g. 3/4 (with --track-logic m-of-n).")] = f"{defaults.CONFIRM_M}/{defaults.CONFIRM_N}",
    delete_misses: Annotated[int, typer.Option(help="Delete a confirmed track after this many consecutive misses (with the score: when its score falls by as much as that many misses).")] = defaults.DELETE_MISSES,
    track_logic: Annotated[str, typer.Option(help="Confirm and delete by the track score (score) or by hit counts (m-of-n).")] = defaults.TRACK_LOGIC,
    false_tracks_per_hour: Annotated[float, typer.Option(help="False-track rate per radar that the track score's confirmation threshold is set for.")] = defaults.FALSE_TRACKS_PER_HOUR,
    report_max_misses: Annotated[int, typer.Option(help="Report a confirmed track only while it has fewer consecutive misses than this (0: until deleted).")] = defaults.REPORT_MAX_MISSES,
    init: Annotated[str, typer.Option(help="Track initiation: one-point or two-point.")] = defaults.INIT,
    tracking_dim: Annotated[Optional[int], typer.Option(help="2 (horizontal) or 3; default from the radars.")] = None,
    default_altitude: Annotated[Optional[float], typer.Option(help="Fixed altitude (m) for 2-D plots without Mode C (default: bounded between the radar horizon and 30 deg elevation).")] = None,
    output_interval: Annotated[Optional[float], typer.Option(help="Report tracks every N s (default: each scan of the first radar).")] = None,
    full_covariance: Annotated[bool, typer.Option(help="Also write the full covariance as cov_i_j columns.")] = False,
    lenient: Annotated[bool, typer.Option(help="Skip and count malformed plot rows instead of stopping.")] = False,
    chunk_rows: Annotated[int, typer.Option(help="Plots read, validated and tracked per chunk (bounds memory, Parquet and CSV alike).")] = defaults.CHUNK_ROWS,
    filter_kind: Annotated[Optional[str], typer.Option("--filter", help="Filter family: kalman-psi (default: Kalman with the manoeuvre switch), kalman, imm, static-bank, or any registered kind.")] = None,
    model_set: Annotated[Optional[str], typer.Option("--model-set", help="Model set of --filter imm or static-bank: cv-ct-noisy (default), cv-ct, noise-levels; cv-ca, full and cv-ca-singer with --model singer.")] = None,
    association_rule: Annotated[Optional[str], typer.Option("--association-rule", help="Association rule: llr (default: likelihood ratio against the clutter density), nn (coordinates only), ml, fuzzy (IFF and transponder code through spec 003's membership tables), crisp (identity mismatches forbidden).")] = None,
    association_mode: Annotated[Optional[str], typer.Option("--association-mode", help="global (default: one assignment per scan) or sequential (plot by plot, spec 003's paper).")] = None,
    identity_error_p: Annotated[Optional[float], typer.Option("--identity-error-p", help="Per-reply error probability behind identity_p (default 0.05).")] = None,
    missing_iff: Annotated[Optional[str], typer.Option("--missing-iff", help="Fuzzy rule, plot without IFF reply: undetermined (default, the paper's table) or neutral.")] = None,
    range_rate_positive_closing: Annotated[bool, typer.Option("--range-rate-positive-closing", help="The plots' range_rate_mps is positive for closing targets; negate it into skytrack's convention (dD/dt, positive opening).")] = False,
    units_confirmed: Annotated[bool, typer.Option("--units-confirmed", help="Track plots whose values look like km or radians as metres and degrees all the same.")] = False,
    config_file: Annotated[Optional[Path], typer.Option("--config", help="Tracker configuration (YAML or JSON, one section per component; see docs/design.md). Options given on the command line override it.")] = None,
    adsb: Annotated[Optional[Path], typer.Option("--adsb", help="ADS-B reports (FORMATS.md adsb, OpenSky or traffic state vectors, or the CAT021 reports of an .ast / .pcap recording): label tracks with the icao24 and callsign that spec 001's sequential test identifies for them.")] = None,
    adsb_fuse: Annotated[bool, typer.Option("--adsb-fuse", help="With --adsb: rows of identified tracks carry the radar/ADS-B fused state (the pair's joint filter, spec 001 R14).")] = False,
    only_sensor: Annotated[Optional[list[str]], typer.Option("--sensor", help="Track the plots of this sensor only (repeat for several); the other sensors' plots are read and checked, not tracked.")] = None,
    reports: Annotated[bool, typer.Option("--reports", help="Also write NAME.reports.parquet: the plots every confirmed track took (position and covariance in the common frame), for `skytrack identify tracks` between two radars.")] = False,
) -> None:
    """Track plots of one or more radars and write confirmed tracks (FORMATS.md)."""
    from skytrack.app.run import run_tracking
    from skytrack.tracker import TrackerConfig

    confirm_m, confirm_n = _parse_confirm(confirm)
    options = {
        "model": model, "cv_q": q, "singer_tau_s": tau, "singer_sigma_a": sigma_a, "discretization": discretization,
        "manoeuvre_q_scale": manoeuvre_scale, "p_gate": p_gate, "gate_threshold": gate_threshold,
        "confirm_m": confirm_m, "confirm_n": confirm_n, "delete_misses": delete_misses, "init": init,
        "tracking_dim": tracking_dim, "default_altitude_m": default_altitude, "output_interval_s": output_interval,
        "full_covariance": full_covariance, "track_logic": track_logic, "false_tracks_per_hour": false_tracks_per_hour,
        "report_max_misses": report_max_misses,
    }
    if config_file is None:
        config = TrackerConfig(**options)
    else:
        # the file is the base; only options typed on the command line override it
        parameter = {"cv_q": "q", "singer_tau_s": "tau", "singer_sigma_a": "sigma_a", "manoeuvre_q_scale": "manoeuvre_scale",
                     "confirm_m": "confirm", "confirm_n": "confirm", "default_altitude_m": "default_altitude",
                     "output_interval_s": "output_interval"}
        given = {name: value for name, value in options.items()
                 if getattr(ctx.get_parameter_source(parameter.get(name, name)), "name", "") == "COMMANDLINE"}
        config = TrackerConfig.from_file(config_file).replace(**given)
    if filter_kind is not None:
        config = config.replace(filter_kind=filter_kind)
    if model_set is not None:
        config = config.replace(model_set=model_set)
    config = _association_options(config, association_rule, association_mode, missing_iff)
    if identity_error_p is not None:
        if not 0.0 < identity_error_p < 0.5:
            _fail(f"--identity-error-p must lie in (0, 0.5), got {identity_error_p}")
        config = config.replace(identity_error_p=identity_error_p)
    if chunk_rows < 1:
        _fail(f"--chunk-rows must be at least 1, got {chunk_rows}")
    if adsb_fuse and adsb is None:
        _fail("--adsb-fuse needs --adsb")
    identification = None
    if adsb is not None:
        from skytrack.app.identification import AdsbIdentificationConfig

        identification = AdsbIdentificationConfig(fuse=adsb_fuse)
    with _progress() as progress:
        summary = run_tracking(plots, sensors, out, config, lenient=lenient, chunk_rows=chunk_rows, progress=progress,
                               units_confirmed=units_confirmed, range_rate_positive_closing=range_rate_positive_closing,
                               adsb_path=adsb, identification=identification, write_reports=reports,
                               only_sensors=only_sensor)
    _print_tracking_summary(summary)


def _parse_confirm(text: str) -> tuple[int, int]:
    try:
        m, n = (int(part) for part in text.split("/"))
    except ValueError:
        raise ValueError(f"--confirm must look like M/N (e.g. 3/4), got {text!r}") from None
    return m, n


def _print_tracking_summary(summary) -> None:
    """Print a :class:`skytrack.app.run.RunSummary`."""
    stats = summary.stats
    report = summary.report
    if report is not None and not report.ok:
        error_console.print(f"[yellow]lenient read:[/] {report}", highlight=False)
    for warning in summary.warnings:
        error_console.print(f"[yellow]warning:[/] {warning}")
    table = Table(title="tracking", show_header=False)
    table.add_row("plots", f"{summary.plots} ({stats.get('plots_assigned', 0)} assigned)")
    table.add_row("tracks confirmed", str(stats.get("tracks_confirmed", 0)))
    table.add_row("tentative tracks dropped", str(stats.get("tentative_dropped", 0)))
    table.add_row("tracks deleted", str(stats.get("tracks_deleted", 0)))
    if stats.get("plots_height_above_slant_range"):
        table.add_row("plots placed over the radar", f"{stats['plots_height_above_slant_range']} (height above slant range)")
    table.add_row("tracking", f"{summary.tracking_dim}-D")
    table.add_row("track rows written", f"{summary.track_rows} -> {summary.tracks_file}")
    if summary.identity_events_file is not None:
        table.add_row("identity events", f"{summary.identity_event_rows} -> {summary.identity_events_file}")
    elif summary.no_identity_events_reason:
        table.add_row("identity events", f"none: {summary.no_identity_events_reason}")
    if summary.identification is not None:
        ident = summary.identification
        table.add_row("ADS-B", f"{ident['adsb_reports']} reports from {ident['adsb_addresses']} addresses")
        table.add_row("tracks identified", f"{ident['labelled_tracks']} ({ident['labelled_rows']} rows labelled, "
                                           f"{ident['label_changes']} label changes)")
        if ident["mode_s_conflicts"]:
            table.add_row("Mode S conflicts", f"{ident['mode_s_conflicts']} rows where ADS-B named another address")
    if summary.reports_file is not None:
        table.add_row("track reports", f"{summary.report_rows} -> {summary.reports_file}")
    table.add_row("time", f"{summary.elapsed_s:.2f} s ({summary.plots_per_s:,.0f} plots/s, reading and writing included)")
    console.print(table)
    if summary.no_tracks_reason:
        error_console.print(f"[yellow]no track written:[/] {summary.no_tracks_reason}", highlight=False)


# ---------------------------------------------------------------------------- evaluate
@app.command()
@reports_input_errors
def evaluate(
    tracks: Annotated[Path, typer.Argument(help="Tracks table written by `skytrack track` (or another tool).")],
    truth: Annotated[Path, typer.Option("--truth", help="Truth table (FORMATS.md or OpenSky state vectors).")],
    json_out: Annotated[Optional[Path], typer.Option("--json", help="Metrics JSON to write (default: next to TRACKS).")] = None,
    sensors: Annotated[Optional[Path], typer.Option("--sensors", help="sensors.json (origin for OpenSky truth).")] = None,
    cutoff: Annotated[float, typer.Option(help="OSPA/GOSPA cut-off c (m).")] = 2000.0,
    order: Annotated[float, typer.Option(help="OSPA/GOSPA order p.")] = 2.0,
    gate: Annotated[float, typer.Option(help="Largest track-to-truth distance of an assignment (m).")] = 2000.0,
    start_time: Annotated[Optional[float], typer.Option(help="Time the tracker started (s), for time-to-first-track.")] = None,
) -> None:
    """Compare tracks with truth: GOSPA/OSPA, RMSE, NEES, continuity, breaks, swaps, false tracks."""
    from skytrack.app.evaluate import run_evaluation

    done = run_evaluation(tracks, truth, json_out=json_out, sensors_path=sensors, cutoff_m=cutoff, order=order,
                          association_gate_m=gate, start_time_s=start_time)
    _print_evaluation(done.evaluation, done.json_path)


def _print_evaluation(evaluation, json_path: Path | None) -> None:
    table = Table(title="evaluation against truth")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    for row in evaluation.summary_rows():
        table.add_row(*row)
    console.print(table)
    for note in evaluation.notes:
        console.print(f"[dim]note: {note}[/]")
    if json_path is not None:
        console.print(f"metrics written to {json_path}")


# ---------------------------------------------------------------------------- demo
@app.command()
@reports_input_errors
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Report folder.")] = Path("skytrack-demo"),
    scenario: Annotated[str, typer.Option(help="Scenario file or bundled name.")] = "demo",
    seed: Annotated[Optional[int], typer.Option(help="Seed of the measurement noise.")] = None,
) -> None:
    """Simulate the demo scenario, track it (identifying the tracks with its ADS-B), evaluate it and write a report folder (exit 1 when a check fails)."""
    from skytrack.app.demo import run_demo
    from skytrack.cli.demo import demo_passed, print_demo_checks, print_demo_identification

    with _progress() as progress:
        result = run_demo(out, scenario, seed, progress=progress)
    _print_evaluation(result.evaluation, result.metrics_path)
    print_demo_identification(console, result)
    print_demo_checks(console, result)
    if not demo_passed(result):
        console.print("[bold red]error:[/] a demo check failed (FAIL above); the report folder is written")
        raise typer.Exit(1)

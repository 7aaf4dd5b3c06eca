"""``skytrack identify pair REPORTS``: the sequential pair test of spec 001 on a reports file (R12).

REPORTS is an identification reports table (CSV or Parquet, docs/formats.md "identification
reports": time, system 1|2 or eta|xi, optional track_id, x, y [, z], optional velocities and the
covariance as ``sigma_m`` or ``var_x, var_y, cov_xy``; read by :mod:`skytrack.io.ident_reports`).
The reports of the two systems are merged in time order (system 1 first at equal times) and fed
one by one to :class:`~skytrack.identify.sequential.SequentialPairTest`.  After every report the
command prints the four quadratic forms Q_Jη, Q_Jξ, Q_η, Q_ξ, Λ of (20a), dof, the threshold h of
R5, the decision (same / different / insufficient) and, when a prior (``--init prior --x0 ...
--p0-diag ...``) or an object density (``--object-density``) is configured, the posterior P(same)
of R6 (with the log-determinants, gap G1).

Options: ``--model cv --q Q`` (the CV identification model, white-noise acceleration PSD q),
``--init diffuse|prior``, the threshold modes ``--p-correct P`` (default 0.99) | ``--p-incorrect A``
with ``--noncentrality L`` | ``--min-separation D`` | ``--state-difference ...`` | ``--h H``;
``--track-1/--track-2`` choose the tracks when a system has several; ``--csv FILE`` writes the
printed table.  Bad input exits with code 2 and names the row.  Only typer and rich are imported
at module level.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

console = Console()
error_console = Console(stderr=True)
MODELS = ("cv",)


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _numbers(option: str, text: str | None, count: int | None = None) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(part) for part in text.replace(" ", ",").split(",") if part.strip()]
    except ValueError:
        _fail(f"{option} expects comma-separated numbers, got {text!r}")
    if count is not None and len(values) != count:
        _fail(f"{option} needs {count} values (the state {'[x, y, vx, vy]' if count == 4 else ''}), got {len(values)}")
    return values


def _threshold(p_correct, p_incorrect, noncentrality, min_separation, state_difference, h, n):
    from skytrack.identify.threshold import Threshold

    if sum(v is not None for v in (p_correct, p_incorrect, h)) > 1:
        _fail("give one threshold mode: --p-correct, --p-incorrect (with its design) or --h")
    designs = [v is not None for v in (noncentrality, min_separation, state_difference)]
    if p_incorrect is None and any(designs):
        _fail("--noncentrality, --min-separation and --state-difference go with --p-incorrect")
    difference = _numbers("--state-difference", state_difference, n)
    try:
        if h is not None:
            return Threshold(h=h)
        if p_incorrect is not None:
            return Threshold(p_incorrect=p_incorrect, noncentrality=noncentrality, min_separation_m=min_separation,
                             state_difference=None if difference is None else tuple(difference))
        return Threshold(p_correct=0.99 if p_correct is None else p_correct)
    except ValueError as error:
        _fail(str(error))


def _select_track(arrays, system: int, wanted: str | None, option: str):
    """Rows of ``system``'s track: the only one in the file, or ``wanted``."""
    mine = arrays.system == system
    ids = [t for t in dict.fromkeys(arrays.track_id[mine].tolist()) if t is not None and t == t]
    if wanted is not None:
        if wanted not in ids:
            _fail(f"{option} {wanted!r}: system {system} has tracks {', '.join(map(str, ids)) or '(no track_id)'}")
        return mine & (arrays.track_id == wanted)
    if len(ids) > 1:
        _fail(f"system {system} has {len(ids)} tracks ({', '.join(map(str, ids[:6]))}{', ...' if len(ids) > 6 else ''}): "
              f"choose one with {option}")
    if not mine.any():
        _fail(f"the file has no report of system {system}")
    return mine


def _fmt(value, digits: int = 6) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return f"{value if abs(value) >= 0.5 * 10.0 ** -digits else 0.0:.{digits}f}"  # no "-0.000000"


def identify_pair(
    reports: Annotated[Path, typer.Argument(help="Identification reports (CSV or Parquet; docs/formats.md).")],
    model: Annotated[str, typer.Option("--model", help="Identification model: cv (constant velocity).")] = "cv",
    q: Annotated[float, typer.Option("--q", help="White-noise acceleration PSD q of the CV model [m²/s³].")] = 0.0,
    init: Annotated[str, typer.Option("--init", help="diffuse (exact diffuse start, R3a) or prior (R3b).")] = "diffuse",
    x0: Annotated[Optional[str], typer.Option("--x0", help="Prior mean [x, y, vx, vy] (m, m/s), comma-separated.")] = None,
    p0_diag: Annotated[Optional[str], typer.Option("--p0-diag", help="Prior covariance diagonal [m², m², (m/s)², (m/s)²].")] = None,
    t0: Annotated[Optional[float], typer.Option("--t0", help="Prior epoch [s] (default: the first report's time).")] = None,
    prior_same: Annotated[float, typer.Option("--prior-same", help="Prior probability π of one object.")] = 0.5,
    object_density: Annotated[Optional[float], typer.Option(
        "--object-density", help="β, objects per unit of state space (diffuse start: density-mode posterior, R6).")] = None,
    p_correct: Annotated[Optional[float], typer.Option("--p-correct", help="h = χ²_dof quantile (default 0.99).")] = None,
    p_incorrect: Annotated[Optional[float], typer.Option("--p-incorrect", help="NP: h = ncχ²_dof(α; λ) quantile.")] = None,
    noncentrality: Annotated[Optional[float], typer.Option("--noncentrality", help="Design λ of --p-incorrect.")] = None,
    min_separation: Annotated[Optional[float], typer.Option(
        "--min-separation", help="Design minimum position separation [m] of --p-incorrect (worst direction).")] = None,
    state_difference: Annotated[Optional[str], typer.Option(
        "--state-difference", help="Design state difference δ of --p-incorrect, comma-separated.")] = None,
    h: Annotated[Optional[float], typer.Option("--h", help="Fixed threshold h on Λ (literal; ignores dof).")] = None,
    dof_min: Annotated[Optional[int], typer.Option("--dof-min", help="Decide only from this dof on (default n).")] = None,
    track_1: Annotated[Optional[str], typer.Option("--track-1", help="track_id of system 1 when it has several.")] = None,
    track_2: Annotated[Optional[str], typer.Option("--track-2", help="track_id of system 2 when it has several.")] = None,
    csv: Annotated[Optional[Path], typer.Option("--csv", help="Also write the table to this CSV file.")] = None,
) -> None:
    """The sequential pair test (20a) report by report: four forms, Λ, dof, h, decision, posterior (R12)."""
    import warnings

    import numpy as np
    import pandas as pd

    from skytrack.identify.model import cv_model
    from skytrack.identify.sequential import INSUFFICIENT, SequentialPairTest, merge_order
    from skytrack.io.errors import InputError
    from skytrack.io.ident_reports import read_ident_reports, report_measurements

    if model not in MODELS:
        _fail(f"--model {model!r}: available models are {', '.join(MODELS)}")
    if not q >= 0:
        _fail(f"--q must be >= 0, got {q}")
    if init not in ("diffuse", "prior"):
        _fail(f"--init must be diffuse or prior, got {init!r}")
    if not 0.0 < prior_same < 1.0:
        _fail(f"--prior-same must lie in (0, 1), got {prior_same}")
    if object_density is not None and (init == "prior" or not object_density > 0):
        _fail("--object-density (> 0) is the posterior of a diffuse start; with --init prior the prior gives it")
    try:
        arrays = report_measurements(read_ident_reports(reports))
    except (InputError, OSError) as error:
        _fail(str(error))
    identification = cv_model(arrays.ndim, q)
    n = identification.n
    rule = _threshold(p_correct, p_incorrect, noncentrality, min_separation, state_difference, h, n)
    chosen = _select_track(arrays, 1, track_1, "--track-1") | _select_track(arrays, 2, track_2, "--track-2")
    rows = np.flatnonzero(chosen)
    rows = rows[merge_order(arrays.time[rows], arrays.system[rows])]
    prior = {}
    if init == "prior":
        if x0 is None or p0_diag is None:
            _fail("--init prior needs --x0 and --p0-diag")
        diagonal = _numbers("--p0-diag", p0_diag, n)
        if min(diagonal) <= 0:
            _fail("--p0-diag values must be > 0")
        prior = dict(init="prior", x0=_numbers("--x0", x0, n), P0=np.diag(diagonal),
                     t0=float(arrays.time[rows].min()) if t0 is None else t0)
        if prior["t0"] > arrays.time[rows].min():
            _fail(f"--t0 {t0:g} s is after the first report ({arrays.time[rows].min():g} s)")
    test = SequentialPairTest(identification, 1, **prior)
    posterior_kind = "prior" if init == "prior" else ("density" if object_density is not None else None)
    notes: list[str] = []
    lines = []
    for k, r in enumerate(rows):
        m = int(arrays.m[r])
        try:
            test.add(int(arrays.system[r]), arrays.time[r], arrays.z[r, :m][None], arrays.V[r, :m, :m])
        except ValueError as error:
            _fail(f"{reports}, row {r}: {error}")
        forms = test.forms()
        try:
            decision, threshold = test.decide(rule, dof_min)
            decision, threshold = str(decision[0]), float(threshold[0])
        except ValueError:  # a design from P_eta + P_xi needs both separate filters at full rank
            decision, threshold = INSUFFICIENT, math.nan
        p_same = math.nan
        if posterior_kind is not None:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    p_same = float(test.posterior(prior_same, object_density=object_density)[0])
                except ValueError:
                    p_same = math.nan
            notes += [str(w.message) for w in caught if str(w.message) not in notes]
        lines.append({"report": k + 1, "time": float(arrays.time[r]), "system": int(arrays.system[r]),
                      "track_id": arrays.track_id[r], "Q_Jeta": float(forms.joint_eta[0]),
                      "Q_Jxi": float(forms.joint_xi[0]), "Q_eta": float(forms.eta[0]), "Q_xi": float(forms.xi[0]),
                      "statistic": float(forms.statistic[0]), "dof": int(forms.dof[0]), "threshold": threshold,
                      "decision": decision, "p_same": p_same})
    _print_table(lines, reports, identification, q, init, rule, posterior_kind)
    for note in notes:
        console.print(f"note: {escape(note)}")
    if csv is not None:
        frame = pd.DataFrame(lines)
        if posterior_kind is None:
            frame = frame.drop(columns="p_same")
        frame.to_csv(csv, index=False, float_format="%.10g")
        console.print(f"wrote {csv}")


def _print_table(lines, reports: Path, model, q: float, init: str, rule, posterior_kind) -> None:
    table = Table(title=escape(f"identify pair {reports.name}: CV model ({model.ndim}-D), q = {q:g} m²/s³, {init} start, "
                               f"threshold {rule.describe()}"))
    headers = ["#", "t [s]", "system", "track", "Q_Jη", "Q_Jξ", "Q_η", "Q_ξ", "Λ", "dof", "h", "decision"]
    if posterior_kind is not None:
        headers.append(f"P(same) ({posterior_kind})")
    for header in headers:
        table.add_column(escape(header), justify="right")
    for line in lines:
        track = line["track_id"]
        cells = [str(line["report"]), f"{line['time']:g}", "η" if line["system"] == 1 else "ξ",
                 "–" if track is None or track != track else str(track), _fmt(line["Q_Jeta"]), _fmt(line["Q_Jxi"]),
                 _fmt(line["Q_eta"]), _fmt(line["Q_xi"]), _fmt(line["statistic"]), str(line["dof"]),
                 _fmt(line["threshold"]), line["decision"]]
        if posterior_kind is not None:
            cells.append("–" if math.isnan(line["p_same"]) else f"{line['p_same']:.7g}")
        table.add_row(*(escape(c) for c in cells))
    needed = console.measure(table, options=console.options.update_width(100_000)).maximum
    (console if needed <= console.width else Console(width=needed)).print(table)


def register_pair_command(app: typer.Typer) -> None:
    """Add ``pair`` (R12) to the ``skytrack identify`` sub-app."""
    app.command("pair")(identify_pair)

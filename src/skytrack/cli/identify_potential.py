"""``skytrack identify potential`` and ``threshold``: potential characteristics and NP design (spec 001 R11).

* ``potential`` — a table with one row per threshold r (columns P_ПО, P_НО(A_i), P̄_НО) from
  :func:`skytrack.identify.potential.characteristics` (R9): thresholds ``--r`` (normalised),
  ``--h`` (metres) or ``--r-grid START:STOP:STEP``; offsets ``--A`` (normalised) or ``--delta``
  (metres); ``--delta-range`` / ``--A-range`` for the (27c) average; scattering ``--sigma`` or
  ``--sigma-eta`` + ``--sigma-xi`` (per axis, combined as sigma_i^2 = sigma_i_eta^2 + sigma_i_xi^2);
  ``--mode exact|circular`` (G10: circular takes sigma := max sigma_i, with a warning).
  ``--plot`` draws P_ПО solid, P_НО dashed, P̄_НО dotted against r; ``--csv`` writes the table.
* ``threshold`` — the Neyman-Pearson design of :mod:`skytrack.identify.design` (R10): r, h, r^2 and P_ПО
  for ``--p-incorrect alpha`` at an offset (``--A``, ``--delta`` with ``--sigma``) or over a range
  (``--A-range``, ``--delta-range`` with ``--sigma``), or for ``--p-correct P``.

Values are printed with 10 significant digits.  A bad option prints a one-line error and exits
with code 2.  Only typer and rich are imported at module level.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

console = Console()
error_console = Console(stderr=True)

DEFAULT_R_GRID = "0:6:0.5"
PLOT_POINTS = 601
DIGITS = 10

ListOption = Optional[list[str]]


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _numbers(option: str, values: list[str] | None) -> list[float] | None:
    """Values of a repeatable option; each occurrence may hold comma-separated numbers."""
    if not values:
        return None
    numbers = []
    for text in values:
        for part in str(text).split(","):
            if part.strip():
                try:
                    numbers.append(float(part))
                except ValueError:
                    _fail(f"{option} expects numbers, got {text!r}")
    if not numbers:
        _fail(f"{option} needs at least one value")
    return numbers


def _r_grid(text: str) -> list[float]:
    """START:STOP:STEP, STOP included."""
    parts = text.split(":")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        _fail(f"--r-grid expects START:STOP:STEP, got {text!r}")
    if not (step > 0 and 0 <= start <= stop):
        _fail(f"--r-grid needs 0 <= START <= STOP and STEP > 0, got {text!r}")
    count = int((stop - start) / step + 1e-9) + 1
    if count > 100_000:
        _fail(f"--r-grid gives {count} rows; at most 100000")
    return [start + k * step for k in range(count)]


def _g(value) -> str:
    return "–" if value is None else f"{float(value):.{DIGITS}g}"


def _print_wide(table: Table) -> None:
    """Print without squeezing the columns (the numbers must stay whole when stdout is narrow or a pipe)."""
    needed = console.measure(table, options=console.options.update_width(100_000)).maximum
    (console if needed <= console.width else Console(width=needed)).print(table)


def _warnings_to_stderr(caught) -> None:
    for warning in caught:
        error_console.print(f"[yellow]warning:[/] {escape(str(warning.message))}", highlight=False, soft_wrap=True)


def potential(
    dim: Annotated[int, typer.Option("--dim", help="Number of compared coordinates (2, 3 or any N >= 1).")],
    r: Annotated[ListOption, typer.Option("--r", help="Normalised thresholds r = h / σ (repeat or comma-separate).")] = None,
    h: Annotated[ListOption, typer.Option("--h", help="Distance thresholds h [m] (needs a σ).")] = None,
    sigma: Annotated[Optional[float], typer.Option("--sigma", help="Per-axis sd σ of the estimate difference [m].")] = None,
    sigma_eta: Annotated[Optional[str], typer.Option("--sigma-eta", help="Per-axis sd of system 1 [m] (one value or one per axis).")] = None,
    sigma_xi: Annotated[Optional[str], typer.Option("--sigma-xi", help="Per-axis sd of system 2 [m] (one value or one per axis).")] = None,
    offsets: Annotated[ListOption, typer.Option("--A", help="Normalised offsets A = Δ / σ of the foreign object.")] = None,
    delta: Annotated[ListOption, typer.Option("--delta", help="Separations Δ of the foreign object [m] (needs a σ).")] = None,
    delta_range: Annotated[Optional[tuple[float, float]], typer.Option("--delta-range", help="DMIN DMAX [m]: P̄_НО (27c) for Δ uniform on the range.")] = None,
    A_range: Annotated[Optional[tuple[float, float]], typer.Option("--A-range", help="AMIN AMAX: P̄_НО (27c) for A uniform on the range.")] = None,
    r_grid: Annotated[Optional[str], typer.Option("--r-grid", help=f"Rows r = START:STOP:STEP (default {DEFAULT_R_GRID} without --r/--h).")] = None,
    mode: Annotated[str, typer.Option("--mode", help="exact: statistic (27), any σ_i; circular: literal distance test, σ := max σ_i (G10).")] = "exact",
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Write the curves against r as PNG.")] = None,
    csv: Annotated[Optional[Path], typer.Option("--csv", help="Write the table as CSV.")] = None,
) -> None:
    """P_ПО, P_НО(A) and P̄_НО against the threshold (spec 001 (26)-(28b), R9, R11)."""
    import warnings

    import numpy as np

    from skytrack.identify.potential import characteristics

    if dim < 1:
        _fail(f"--dim must be >= 1, got {dim}")
    if mode not in ("exact", "circular"):
        _fail(f"--mode must be exact or circular, got {mode!r}")
    r_values, h_values = _numbers("--r", r), _numbers("--h", h)
    given = [name for name, value in (("--r", r_values), ("--h", h_values), ("--r-grid", r_grid)) if value]
    if len(given) > 1:
        _fail(f"give one of --r, --h and --r-grid, got {' and '.join(given)}")
    if not given:
        r_values = _r_grid(DEFAULT_R_GRID)
    elif r_grid:
        r_values = _r_grid(r_grid)
    if sigma is not None and (sigma_eta or sigma_xi):
        _fail("give --sigma or --sigma-eta with --sigma-xi, not both")
    if bool(sigma_eta) != bool(sigma_xi):
        _fail("--sigma-eta and --sigma-xi go together")
    A_values, delta_values = _numbers("--A", offsets), _numbers("--delta", delta)
    if A_values and delta_values:
        _fail("give --A or --delta, not both")
    if delta_range is not None and A_range is not None:
        _fail("give --delta-range or --A-range, not both")
    scattering = {}
    if sigma is not None:
        scattering["sigma"] = sigma
    elif sigma_eta:
        scattering["sigma_eta"] = _numbers("--sigma-eta", [sigma_eta])
        scattering["sigma_xi"] = _numbers("--sigma-xi", [sigma_xi])
        if len(scattering["sigma_eta"]) != len(scattering["sigma_xi"]) or len(scattering["sigma_eta"]) not in (1, dim):
            _fail(f"--sigma-eta and --sigma-xi need one value or {dim} (one per axis) each")
    if not scattering and (h_values or delta_values or delta_range is not None):
        _fail("--h, --delta and --delta-range are in metres: give --sigma, or --sigma-eta and --sigma-xi")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result, mean = characteristics(dim, r=r_values, h=h_values, A=A_values, delta=delta_values,
                                           A_range=A_range, delta_range=delta_range, mode=mode, **scattering)
    except ValueError as error:
        _fail(str(error))
    _warnings_to_stderr(caught)
    if A_range is None and delta_range is not None:
        A_range = tuple(float(v) / result.sigma for v in delta_range) if result.sigma else None
    offsets_used = [] if result.A is None else [float(a) for a in result.A]
    columns = {"r": result.r}
    if result.sigma is not None:
        columns["h_m"] = result.r * result.sigma
    columns["p_correct"] = result.p_correct
    labels = {"r": "r = h/σ", "h_m": "h [m]", "p_correct": "P_ПО"}
    for k, a in enumerate(offsets_used):
        key = f"p_incorrect_A{a:.10g}"
        columns[key] = result.p_incorrect[:, k]
        labels[key] = f"P_НО(A={a:.6g}" + (f", Δ={delta_values[k]:g} m)" if delta_values else ")")
    if mean is not None:
        columns["p_incorrect_mean"] = mean
        labels["p_incorrect_mean"] = (f"P̄_НО(Δ∈[{delta_range[0]:g}, {delta_range[1]:g}] m)" if delta_range is not None
                                      else f"P̄_НО(A∈[{A_range[0]:g}, {A_range[1]:g}])")
    sigma_text = f", σ = {result.sigma:g} m" if result.sigma is not None else ""
    table = Table(title=f"Potential characteristics, {dim}-D, {mode} mode{sigma_text}")
    for key in columns:
        table.add_column(escape(labels[key]), justify="right")
    for i in range(len(result.r)):
        table.add_row(*(_g(columns[key][i]) for key in columns))
    _print_wide(table)
    if csv is not None:
        import pandas as pd

        csv.parent.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(columns).to_csv(csv, index=False, float_format="%.15g")
        console.print(f"wrote {csv}")
    if plot is not None:
        from skytrack.studies.identification.common import pyplot, save_figure
        from skytrack.studies.identification.potential_study import draw_curves, mean_label, potential_curves

        top = max(float(np.max(result.r)), 1e-9)
        fine = np.linspace(0.0, top if top > 0.5 else 6.0, PLOT_POINTS)
        curves = potential_curves(dim, fine, offsets_used, A_range)
        fig, ax = pyplot().subplots(figsize=(7.5, 5.4))
        draw_curves(ax, curves, offsets_used, mean_label(A_range, result.sigma) if A_range is not None else None)
        ax.set_xlabel("normalised threshold r = h / σ [–]")
        ax.set_title(f"Potential characteristics of identification, {dim}-D ({mode} mode{sigma_text})")
        fig.tight_layout()
        save_figure(fig, plot)
        console.print(f"wrote {plot}")


def threshold(
    dim: Annotated[int, typer.Option("--dim", help="Number of compared coordinates (degrees of freedom).")],
    p_incorrect: Annotated[Optional[float], typer.Option("--p-incorrect", help="Allowed P_НО = α (Neyman–Pearson).")] = None,
    p_correct: Annotated[Optional[float], typer.Option("--p-correct", help="Required P_ПО.")] = None,
    offset: Annotated[Optional[float], typer.Option("--A", help="Normalised offset A = Δ / σ of the foreign object.")] = None,
    delta: Annotated[Optional[float], typer.Option("--delta", help="Separation Δ of the foreign object [m] (needs --sigma).")] = None,
    delta_range: Annotated[Optional[tuple[float, float]], typer.Option("--delta-range", help="DMIN DMAX [m]: design on P̄_НО (27c), Δ uniform (needs --sigma).")] = None,
    A_range: Annotated[Optional[tuple[float, float]], typer.Option("--A-range", help="AMIN AMAX: design on P̄_НО (27c), A uniform.")] = None,
    sigma: Annotated[Optional[float], typer.Option("--sigma", help="Per-axis sd σ of the estimate difference [m]; gives h = r σ.")] = None,
) -> None:
    """Neyman–Pearson threshold: r, h, r² and P_ПО (spec 001 R10, R11)."""
    from skytrack.identify.design import threshold_for_p_correct, threshold_for_p_incorrect

    if dim < 1:
        _fail(f"--dim must be >= 1, got {dim}")
    if (p_incorrect is None) == (p_correct is None):
        _fail("give exactly one of --p-incorrect and --p-correct")
    if sigma is not None and not sigma > 0:
        _fail(f"--sigma must be > 0, got {sigma}")
    designs = [name for name, value in (("--A", offset), ("--delta", delta), ("--delta-range", delta_range),
                                        ("--A-range", A_range)) if value is not None]
    if (delta is not None or delta_range is not None) and sigma is None:
        _fail("--delta and --delta-range are in metres: give --sigma")
    try:
        if p_correct is not None:
            if designs:
                _fail(f"--p-correct needs no offset ({', '.join(designs)} given)")
            design = threshold_for_p_correct(p_correct, dim, sigma=sigma)
            what = f"P_ПО = {p_correct:g}"
        else:
            if len(designs) != 1:
                _fail("--p-incorrect needs one of --A, --delta, --delta-range and --A-range"
                      + (f" (got {', '.join(designs)})" if designs else ""))
            if delta is not None:
                offset = delta / sigma
            if delta_range is not None:
                A_range = (delta_range[0] / sigma, delta_range[1] / sigma)
            if offset is not None:
                design = threshold_for_p_incorrect(p_incorrect, dim, A=offset, sigma=sigma)
                what = f"P_НО(A = {offset:.6g}) = {p_incorrect:g}"
            else:
                design = threshold_for_p_incorrect(p_incorrect, dim, A_range=A_range, sigma=sigma)
                what = f"P̄_НО(A ∈ [{A_range[0]:.6g}, {A_range[1]:.6g}]) = {p_incorrect:g}"
    except ValueError as error:
        _fail(str(error))
    table = Table(title=f"Neyman–Pearson threshold, {dim}-D: {what}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_row("r = h/σ (normalised distance threshold)", _g(design.r))
    table.add_row(escape("h [m]"), _g(design.h) if design.h is not None else "– (give --sigma)")
    table.add_row("r² (threshold on the statistic l)", _g(design.l_threshold))
    table.add_row("P_ПО (correct identification)", _g(design.p_correct))
    if design.p_incorrect is not None:
        table.add_row("P̄_НО reached" if design.A_range is not None else "P_НО reached", _g(design.p_incorrect))
    _print_wide(table)


def register_potential_commands(app: typer.Typer) -> None:
    """Add ``potential`` and ``threshold`` to the ``skytrack identify`` sub-app."""
    app.command("potential")(potential)
    app.command("threshold")(threshold)

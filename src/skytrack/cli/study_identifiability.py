"""``skytrack study ident-example / ident-radar``: spec 002 §6 E1 and E2 (identifiability, R5-R10).

* ``ident-example`` — E1, the paper's example of §3.5 (eq. 14): det M, κ, σ_χ over f16 ∈ [−1, 1] for
  f15 ∈ {0, 2}, TV2's local/global timeline (R7, G5) and TV6's two-step window (R8, G6)
  (:mod:`skytrack.studies.identifiability.example`);
* ``ident-radar`` — E2, which parameters radar data identify: TV8 and TV9 next to the spec's tables,
  σ_χ(t) of the turn rate for pos, ṙ, pos+ṙ and ψ(t) along the E3 track with per-step and global
  verdicts, and the radar set-ups (ct-omega / ca-accel with biases under pos, ṙ, pos+ṙ, polar,
  polar+ṙ) with their culprits (R6) (:mod:`skytrack.studies.identifiability.radar_study`).

Both commands take ``--out``, ``--seed``, ``--trials``, ``--check`` and ``--json``; they write CSV +
PNG + a JSON summary, print rich tables with each expected value next to the computed one and a
PASS/FAIL verdict (``--json``: the JSON summary on stdout instead).  With ``--check`` a failed
expectation exits with code 1; a bad option exits with code 2.  The studies are deterministic (no
Monte Carlo): ``--seed`` and ``--trials`` are accepted like every study's and recorded.  Only typer
and rich are imported at module level; :func:`register_identifiability_studies` adds the commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from skytrack.cli.study_output import print_wide

console = Console()
error_console = Console(stderr=True)

OutOption = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
SeedOption = Annotated[int, typer.Option("--seed", help="Accepted like every study's; these studies draw no random numbers.")]
TrialsOption = Annotated[int, typer.Option("--trials", help="Accepted like every study's; these studies have no Monte Carlo.")]
CheckOption = Annotated[bool, typer.Option("--check", help="Exit with code 1 if an expected value of the spec fails.")]
JsonOption = Annotated[bool, typer.Option("--json", help="Print the JSON summary on stdout instead of the tables.")]


def _fail(message: str) -> None:
    from skytrack.cli.study_verdicts import fail_option

    fail_option(error_console, message)


def _table(title: str, columns, rows) -> Table:
    table = Table(title=escape(title))
    for column in columns:
        table.add_column(escape(column), overflow="fold")
    for row in rows:
        table.add_row(*(escape(str(cell)) for cell in row))
    return table


def _number(value: float) -> str:
    """6 significant digits; "—" where R9 leaves σ_χ undefined (not identifiable)."""
    return "—" if value != value else f"{value:.6g}"


def _verdict(passed: bool) -> str:
    return "PASS" if passed else "FAIL"


def _finish(name: str, checks, paths: dict, check: bool, as_json: bool) -> None:
    """Print the expected values with PASS/FAIL (or the JSON summary); exit 1 under ``--check`` on a failure."""
    from skytrack.cli.study_verdicts import report_failures, verdicts_table

    if as_json:
        typer.echo(Path(paths["json"]).read_text(), nl=False)
        if check and not all(c.passed for c in checks):
            raise typer.Exit(code=1)
        return
    print_wide(console, verdicts_table(f"{name}: expected values (spec 002 §5, §6)", checks,
                                       ("expected value", "computed", "spec", "verdict")))
    console.print("wrote " + ", ".join(str(p) for p in paths.values()))
    report_failures(console, checks, check, all_held=f"all {len(checks)} expected values hold")


def _check_trials(trials: int) -> None:
    if trials < 1:
        _fail(f"--trials must be >= 1, got {trials}")


# --------------------------------------------------------------------------- E1 ident-example

#: f16 values shown in the printed sweep table (the CSV holds all 201)
SHOWN_F16 = (-1.0, -0.5, -0.1, -0.01, 0.0, 0.01, 0.1, 0.5, 1.0)


def ident_example(
    out: OutOption = Path("study-ident-example"),
    seed: SeedOption = 1,
    trials: TrialsOption = 1,
    check: CheckOption = False,
    as_json: JsonOption = False,
) -> None:
    """E1: the paper's example — det M = f16², κ, σ_χ over f16; TV2 local vs global; TV6 window (spec 002 §6)."""
    from skytrack.studies.identifiability import example

    _check_trials(trials)
    result = example.run_example(out)
    if not as_json:
        sweep = result["sweep"]
        shown = sweep[sweep["f16"].round(12).isin(SHOWN_F16)]
        print_wide(console, _table(
            "ident-example: sweep of f16 (V_η = I; 201 points per f15 in the CSV)",
            ("f15", "f16", "det M", "f16²", "κ", "κ expected", "σ_χ1", "σ_χ2", "√(f15²+1)/|f16|", "R5 verdict",
             "literal det", "Z"),
            ([f"{r.f15:g}", f"{r.f16:g}", f"{r.det:.6g}", f"{r.det_expected:.6g}", f"{r.kappa:.10f}",
              f"{r.kappa_expected:.10f}", _number(r.sigma_chi1), _number(r.sigma_chi2), _number(r.sigma_chi2_expected),
              r.verdict, r.verdict_det, r.zero_influence or "—"] for r in shown.itertuples())))
        timeline = result["tv2"]
        print_wide(console, _table(
            "TV2: local verdicts, f15 = 1, f16(k−1) = float cos(πk/4)",
            ("variant", "k", "f16(k−1)", "det M (literal)", "κ", "R5 (svd)", "literal det (det_tol = 0)", "Z"),
            ([r.variant, r.k, f"{r.f16:.17g}", f"{r.det:.17g}", f"{r.kappa:.15f}", r.verdict_svd, r.verdict_det,
              r.zero_influence or "—"] for r in timeline.itertuples())))
        for variant, summary in result["tv2_summary"].items():
            console.print(escape(f"TV2 {variant}: global (svd) {summary['global_svd']}, failing k = "
                                 f"{summary['failing_svd']}; global (literal det) {summary['global_det']}, "
                                 f"failing k = {summary['failing_det']}"))
        window = result["tv6"]
        print_wide(console, _table(
            "TV6: TV3's F with f16 = 0 — one step vs a two-step window (R8)",
            ("N_w", "rows of S", "verdict", "κ", "Z", "S^(N_w)"),
            ([r.window, r.rows, r.verdict, f"{r.kappa:.10f}", r.zero_influence or "—", r.sensitivity]
             for r in window.itertuples())))
    _finish("ident-example", result["checks"], result["paths"], check, as_json)


# --------------------------------------------------------------------------- E2 ident-radar

#: times t_k (s) shown in the printed σ_χ(t) table (the CSV holds every step)
SHOWN_TIMES = (1, 30, 60, 75, 81, 82, 91, 120, 152, 160, 166, 167, 168, 180, 212, 272)


def ident_radar(
    out: OutOption = Path("study-ident-radar"),
    seed: SeedOption = 1,
    trials: TrialsOption = 1,
    T: Annotated[float, typer.Option("--T", help="Sampling interval T in s along the E3 track (§6 E2: 1).")] = 1.0,
    window: Annotated[int, typer.Option("--window", help="R8 window N_w for the track and set-up verdicts (paper: 1).")] = 1,
    check: CheckOption = False,
    as_json: JsonOption = False,
) -> None:
    """E2: which parameters radar data identify — TV8, TV9, σ_χ(t) along the E3 track, set-ups with culprits."""
    from skytrack.studies.identifiability import radar_setups, radar_study

    _check_trials(trials)
    if not T > 0:
        _fail(f"--T must be > 0, got {T}")
    if not 1 <= window <= 10:
        _fail(f"--window must be between 1 and 10, got {window}")
    result = radar_study.run_radar(out, T, window)
    if not as_json:
        _print_radar(result, radar_setups)
        if T != 1.0 or window != 1:
            console.print(escape(f"note: §6 E2's σ_χ values and the built culprit cases are for T = 1 s, N_w = 1; "
                                 f"with T = {T:g} s, N_w = {window} they are reported above, not checked."))
    _finish("ident-radar", result["checks"], result["paths"], check, as_json)


def _print_radar(result: dict, radar_setups) -> None:
    tv8 = result["tv8"]
    print_wide(console, _table(
        "TV8: one step at p = (30 km, 0), T = 1 s, σ = (50 m, 50 m, 1 m/s) — computed | spec",
        ("parameters", "geometry", "set", "verdict", "κ", "Z", "D", "m<p", "spec verdict", "spec κ", "spec Z",
         "spec D", "match"),
        ([r.parameters, r.geometry, r.set, r.verdict, f"{r.kappa:.6f}", r.Z or "—", r.D or "—", r.m_lt_p,
          r.expected_verdict, "—" if r.expected_kappa != r.expected_kappa else f"{r.expected_kappa:.6f}",
          r.expected_Z or "—", r.expected_D or "—", _verdict(r.matches)] for r in tv8.itertuples())))
    polar = result["tv8_polar"]
    print_wide(console, _table(
        "TV8 polar: (r, az) with σ_r = 50 m, σ_az = 0.1° in place of (x, y) — same decision as the (x, y) cell?",
        ("parameters", "geometry", "set", "verdict", "κ", "Z", "D", "(x, y) cell verdict", "(x, y) κ", "match"),
        ([r.parameters, r.geometry, r.set, r.verdict, f"{r.kappa:.6f}", r.Z or "—", r.D or "—", r.expected_verdict,
          "—" if r.expected_kappa != r.expected_kappa else f"{r.expected_kappa:.6f}", _verdict(r.matches)]
         for r in polar.itertuples())))
    tv9 = result["tv9"]
    print_wide(console, _table(
        "TV9: full state (x, y, v_x, v_y, a_x, a_y, b_x) over N_w = 10 steps (R8, G3) — computed | spec",
        ("measurements", "verdict", "κ", "D", "spec verdict", "spec κ", "spec D", "match", "R6 message"),
        ([r.set, r.verdict, f"{r.kappa:.3g}", r.D or "—", r.expected_verdict,
          "—" if r.expected_kappa != r.expected_kappa else f"≈ {r.expected_kappa:g}", r.expected_D or "—",
          _verdict(r.matches), r.messages or "—"] for r in tv9.itertuples())))
    track = result["track"]
    shown = track[track["t_s"].round(9).isin([float(t) for t in SHOWN_TIMES])]
    print_wide(console, _table(
        "σ_χ(t) of the turn rate ω along the E3 track (°/s; σ_pos = 20 m, σ_ṙ = 0.5 m/s; interval [t_k−1, t_k])",
        ("t_k [s]", "ω [°/s]", "ψ [°]", "pos", "σ_pos/(T²v/2)", "ṙ", "σ_ṙ/(T v sin ψ)", "pos+ṙ", "verdicts pos/ṙ/pos+ṙ"),
        ([f"{r.t_s:g}", f"{r.omega_true_deg_s:g}", f"{r.psi_deg:.3f}", f"{r.sigma_pos_deg_s:.4f}",
          f"{r.sigma_pos_closed_form_deg_s:.4f}", f"{getattr(r, 'sigma_rdot_deg_s'):.4f}",
          f"{r.sigma_rdot_closed_form_deg_s:.4f}", f"{track.loc[r.Index, 'sigma_pos+rdot_deg_s']:.4f}",
          "/".join(track.loc[r.Index, [f'verdict_{s}' for s in ('pos', 'rdot', 'pos+rdot')]])]
         for r in shown.itertuples())))
    steps = result["steps"]
    print_wide(console, _table(
        f"per-step summary along the track (R7 over the intervals, N_w = {result['options']['window']})",
        ("set", "steps", "identifiable", "weak", "not", "global", "failing k", "σ_χ min/median/max [°/s]",
         "worst steps"),
        ([r.set, r.steps, r.identifiable, r.weak, r.not_identifiable, r.global_, r.failing_steps or "none",
          f"{r.sigma_min_deg_s:.3f} / {r.sigma_median_deg_s:.3f} / {r.sigma_max_deg_s:.3f}", r.worst_steps]
         for r in steps.rename(columns={"global": "global_"}).itertuples())))
    setups = result["setups"]
    print_wide(console, _table(
        "radar set-ups along the E3 track: which parameters are identifiable, per step and globally "
        "(a bias whose channel is not in the set has no row acting on it)",
        ("parameters", "set", "ident.", "weak", "not", "global", "determined at every step", "Z culprits (steps)",
         "D culprits (steps)", "m<p", "min κ"),
        ([r.parameters, r.set, r.identifiable, r.weak, r.not_identifiable, r.global_, r.determined_every_step or "—",
          r.Z_culprits or "—", r.D_culprits or "—", r.m_lt_p, f"{r.kappa_min:.3g}"]
         for r in setups.rename(columns={"global": "global_"}).itertuples())))
    print_wide(console, _answer_table(setups))
    console.print("[bold]culprit cases (R6 message at the first step that is weak or not identifiable):[/bold]")
    for (parameters, set_name), (verdict, _, _, why) in radar_setups.CULPRIT_CASES.items():
        row = setups[(setups["parameters"] == parameters) & (setups["set"] == set_name)].iloc[0]
        console.print(escape(f"  {{{parameters}}} with {set_name} ({why}): global {row['global']}; "
                             f"{row['first_message'] or 'no culprit'}"), soft_wrap=True)


def _answer_table(setups) -> Table:
    """Position-only against position + Doppler, one row per parameter set: global verdict, per-step
    counts (identifiable/weak/not) and the culprits."""
    def cell(parameters: str, set_name: str) -> str:
        r = setups[(setups["parameters"] == parameters) & (setups["set"] == set_name)].iloc[0]
        culprits = "; ".join(part for part in (f"Z: {r['Z_culprits']}" if r["Z_culprits"] else "",
                                               f"D: {r['D_culprits']}" if r["D_culprits"] else "") if part)
        return (f"{r['global']} ({r['identifiable']}/{r['weak']}/{r['not_identifiable']})"
                + (f" — {culprits}" if culprits else ""))

    rows = [[f"{{{parameters}}}", cell(parameters, "pos"), cell(parameters, "pos+rdot")]
            for parameters in dict.fromkeys(setups["parameters"])]
    return _table("answer: identifiable from position only vs position + Doppler along the E3 track — "
                  "global verdict (steps identifiable/weak/not) and culprits",
                  ("parameters", "position only (σ 20 m)", "position + Doppler (σ 20 m, 0.5 m/s)"), rows)


def register_identifiability_studies(app: typer.Typer) -> None:
    """Add spec 002 §6 E1, E2 to the ``skytrack study`` sub-app."""
    app.command("ident-example")(ident_example)
    app.command("ident-radar")(ident_radar)

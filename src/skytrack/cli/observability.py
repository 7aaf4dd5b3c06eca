"""``skytrack observability``: the joint observability / identifiability checker of spec 002 (R17).

Sub-commands:

* ``check`` — R5's record for one model, state and measurement set (verdict, κ, det, singular
  values, ρ_j, Z, D, m < p, σ_χ of R9) and the R6 culprit messages; ``paper-example`` is §3.5's
  six-state example (TV1 / TV3's F with f15, f16), ``ct-omega`` and ``ca-accel`` the radar models
  of TV8 (R4, R10) with optional measurement biases; ``--window`` / ``--unknown`` are R8's options.
* ``sequence FILE.npz`` — R7's local / global record for a stored sequence F[k], H[k], h_a, V_η[k].

Only typer and rich are imported at module level; each command imports the library when it runs.
Input problems end in a one-line error and exit code 2.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

observability_app = typer.Typer(
    help="Joint observability and identifiability of states and parameters (spec 002 R5-R9, R17).",
    no_args_is_help=True,
)

console = Console()
error_console = Console(stderr=True)

MODELS = ("paper-example", "ct-omega", "ca-accel")
BIAS_CHANNELS = ("x", "y", "rdot")


def _fail(message: str) -> None:
    error_console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _numbers(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{what} must be comma-separated numbers, not {text!r}") from None


def _fmt(value: float) -> str:
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.10g}"


def _record(checks, i: int) -> dict:
    """R5's record of step i as plain JSON-able values."""
    return {
        "step": int(checks.steps[i]),
        "verdict": checks.verdicts[i],
        "kappa": float(checks.kappa[i]),
        "det": float(checks.det[i]),
        "singular_values": [float(v) for v in checks.singular_values[i]],
        "influence_ratio": dict(zip(checks.names, map(float, checks.influence_ratio[i]))),
        "zero_influence": checks.zero_influence_names(i),
        "indistinguishable": checks.indistinguishable_names(i),
        "fewer_channels": bool(checks.fewer_channels[i]),
        "precision": dict(zip(checks.names, [None if math.isnan(v) else float(v) for v in checks.precision[i]])),
        "messages": checks.messages(i),
    }


def _print_record(checks, i: int) -> None:
    record = _record(checks, i)
    table = Table(title=escape(f"Identifiability over {checks.interval(i)} (method {checks.method})"))
    table.add_column("quantity")
    table.add_column("value")
    table.add_row("verdict", record["verdict"])
    table.add_row("κ", _fmt(record["kappa"]))
    table.add_row("det(SᵀS)", _fmt(record["det"]))
    table.add_row("σ (equilibrated)", ", ".join(_fmt(v) for v in record["singular_values"]))
    for name in checks.names:
        table.add_row(f"ρ_{name}", _fmt(record["influence_ratio"][name]))
    table.add_row("Z (no influence)", ", ".join(record["zero_influence"]) or "∅")
    table.add_row("D (indistinguishable)", ", ".join(record["indistinguishable"]) or "∅")
    table.add_row("m < p", str(record["fewer_channels"]))
    for name in checks.names:
        table.add_row(f"σ_χ {name}", _fmt(record["precision"][name]))
    console.print(table)
    for message in record["messages"]:
        console.print(f"• {message}", highlight=False, soft_wrap=True, markup=False)


def _paper_example(f15: float, f16: float):
    """§3.5: TV3's F with f15, f16; h measures x1 and x5; the parameters are a1 = x5, a2 = x6."""
    import numpy as np

    F = np.array([[1, 0.5, 0, 0, f15, f16], [0, 1, 0.1, 0, 0.5, 0.7], [0, 0, 1, 0.1, 0.2, 0],
                  [0, 0, 0, 1, 0, 0.4], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1.0]])
    H = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0]])
    h_a = np.array([[0.0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]])
    return H, F, h_a


def _radar_check(model_name, biases, kinds, state, T, variances, method, det_tol, window, unknown):
    """TV8's construction: the model (with bias parameters), its measurement and the states along φ."""
    from dataclasses import replace

    import numpy as np

    from skytrack.analysis.identifiability_along import check_along
    from skytrack.models.augmented import ca_accel, ct_omega
    from skytrack.models.augmented_measurements import CHANNEL_UNITS, measurement_for

    base = ct_omega() if model_name == "ct-omega" else ca_accel()
    measurement = measurement_for(base, kinds)
    for channel in biases:
        if channel in measurement.channels:
            measurement = measurement.with_bias(channel)
        else:  # a bias whose channel is not measured: no row acts on it (exactly zero influence)
            measurement = replace(measurement, state_dim=measurement.state_dim + 1)
    model = base.with_parameters([f"b_{c}" for c in biases], [CHANNEL_UNITS[c] for c in biases],
                                 [1e-6] * len(biases)) if biases else base
    if len(state) < 4 or len(state) > model.dim:
        raise ValueError(f"--state needs 4 to {model.dim} values {model.components}, got {len(state)}")
    start = np.zeros(model.dim)
    start[: len(state)] = state
    states = [start]
    for _ in range(window):
        states.append(model.phi(states[-1], T))
    noise_cov = np.diag([variances[c] for c in measurement.channels])
    record = check_along(model, measurement, np.stack(states), T, noise_cov=noise_cov, method=method,
                         det_tol=det_tol, window=window, unknown=unknown)
    return record.checks


@observability_app.command("check")
def check(
    model: Annotated[str, typer.Option(help="paper-example, ct-omega or ca-accel")] = "paper-example",
    bias: Annotated[Optional[list[str]], typer.Option(help="bias parameter on channel x, y or rdot (repeatable)")] = None,
    meas: Annotated[str, typer.Option(help="pos, rdot, pos,rdot, polar or polar,rdot")] = "pos,rdot",
    state: Annotated[str, typer.Option(help="x,y,vx,vy[,parameters] of x(k-1) in SI units")] = "30000,0,0,200",
    T: Annotated[float, typer.Option("--T", help="step length T [s]")] = 1.0,
    sigma_pos: Annotated[Optional[float], typer.Option(help="σ of x, y [m] (paper-example: of both channels; default 1 there, 50 otherwise)")] = None,
    sigma_rdot: Annotated[float, typer.Option(help="σ of ṙ [m/s]")] = 1.0,
    sigma_range: Annotated[Optional[float], typer.Option(help="σ of range [m] (default --sigma-pos)")] = None,
    sigma_az: Annotated[float, typer.Option(help="σ of azimuth [deg]")] = 0.1,
    method: Annotated[str, typer.Option(help="svd (R5) or det (literal eq. 14)")] = "svd",
    det_tol: Annotated[float, typer.Option(help="tolerance of the det method")] = 0.0,
    window: Annotated[int, typer.Option(help="R8 window N_w (steps stacked)")] = 1,
    unknown: Annotated[str, typer.Option(help="params (paper) or all (whole x(k-1), R8)")] = "params",
    f15: Annotated[float, typer.Option("--f15", help="paper-example: F[1,5]")] = 2.0,
    f16: Annotated[float, typer.Option("--f16", help="paper-example: F[1,6]")] = 3.0,
    as_json: Annotated[bool, typer.Option("--json", help="print the record as JSON")] = False,
) -> None:
    """R5's record (R6 messages, R9 precision) for one model, state and measurement set."""
    try:
        if model not in MODELS:
            raise ValueError(f"--model must be one of {', '.join(MODELS)}, not {model!r}")
        if method not in ("svd", "det"):
            raise ValueError(f"--method must be svd or det, not {method!r}")
        unknown_mode = {"params": "parameters", "all": "all"}.get(unknown)
        if unknown_mode is None:
            raise ValueError(f"--unknown must be params or all, not {unknown!r}")
        if window < 1:
            raise ValueError("--window must be ≥ 1")
        if T <= 0:
            raise ValueError("--T must be positive")
        for s, name in ((sigma_pos, "--sigma-pos"), (sigma_rdot, "--sigma-rdot"), (sigma_range, "--sigma-range"),
                        (sigma_az, "--sigma-az")):
            if s is not None and not s > 0:
                raise ValueError(f"{name} must be positive")
        if model == "paper-example":
            import numpy as np

            from skytrack.analysis.identifiability_sequence import check_sequence

            if bias:
                raise ValueError("--bias applies to ct-omega and ca-accel only")
            H, F, h_a = _paper_example(f15, f16)
            sigma = 1.0 if sigma_pos is None else sigma_pos
            checks = check_sequence(H, np.repeat(F[None], window, axis=0), h_a, noise_cov=sigma**2 * np.eye(2),
                                    method=method, det_tol=det_tol, window=window, unknown=unknown_mode).checks
        else:
            biases = tuple(bias or ())
            wrong = [b for b in biases if b not in BIAS_CHANNELS]
            if wrong or len(set(biases)) != len(biases):
                raise ValueError(f"--bias takes distinct channels of {', '.join(BIAS_CHANNELS)}, got {list(biases)}")
            kinds = tuple(k.strip() for k in meas.split(",") if k.strip())
            if kinds not in (("pos",), ("rdot",), ("pos", "rdot"), ("polar",), ("polar", "rdot")):
                raise ValueError(f"--meas must be pos, rdot, pos,rdot, polar or polar,rdot, not {meas!r}")
            pos = 50.0 if sigma_pos is None else sigma_pos
            rng = pos if sigma_range is None else sigma_range
            variances = {"x": pos**2, "y": pos**2, "rdot": sigma_rdot**2, "r": rng**2,
                         "az": math.radians(sigma_az) ** 2}
            checks = _radar_check(model, biases, kinds, _numbers(state, "--state"), T, variances, method,
                                  det_tol, window, unknown_mode)
    except (ValueError, KeyError) as exc:
        _fail(str(exc.args[0] if exc.args else exc))
    if as_json:
        console.print_json(json.dumps(_record(checks, 0)))
    else:
        _print_record(checks, 0)


@observability_app.command("sequence")
def sequence(
    file: Annotated[Path, typer.Argument(help="npz with F[k], H[k] (or h), h_a and optional V_eta[k]")],
    method: Annotated[str, typer.Option(help="svd (R5) or det (literal eq. 14)")] = "svd",
    det_tol: Annotated[float, typer.Option(help="tolerance of the det method")] = 0.0,
    window: Annotated[int, typer.Option(help="R8 window N_w")] = 1,
    as_json: Annotated[bool, typer.Option("--json", help="print the record as JSON")] = False,
) -> None:
    """R7's record for a stored sequence: per-step verdicts, global verdict, failing steps, messages."""
    try:
        import numpy as np

        from skytrack.analysis.identifiability_sequence import check_sequence

        if not file.is_file():
            raise ValueError(f"{file}: no such file")
        try:
            data = np.load(file)
        except Exception as exc:  # a corrupt archive raises several kinds of error
            raise ValueError(f"{file}: not a readable npz file ({exc})") from None
        H = data["H"] if "H" in data else data["h"] if "h" in data else None
        missing = [name for name, value in (("F", "F" in data), ("H or h", H is not None), ("h_a", "h_a" in data))
                   if not value]
        if missing:
            raise ValueError(f"{file}: missing arrays {', '.join(missing)}")
        noise_cov = data["V_eta"] if "V_eta" in data else None
        try:
            record = check_sequence(H, data["F"], data["h_a"], noise_cov=noise_cov, method=method,
                                    det_tol=det_tol, window=window)
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise ValueError(f"{file}: {exc}") from None
    except (ValueError, KeyError) as exc:
        _fail(str(exc.args[0] if exc.args else exc))
    checks = record.checks
    if as_json:
        console.print_json(json.dumps({
            "steps": [_record(checks, i) for i in range(len(checks))],
            "global_verdict": record.global_verdict,
            "failing_steps": record.failing_steps,
            "weak_steps": record.weak_steps,
            "messages": record.messages(),
        }))
        return
    table = Table(title=f"Local identifiability per step (method {checks.method}, window {checks.window})")
    for column in ("k", "verdict", "κ", "det(SᵀS)", "Z", "D"):
        table.add_column(column)
    for i in range(len(checks)):
        table.add_row(str(int(checks.steps[i])), checks.verdicts[i], _fmt(float(checks.kappa[i])),
                      _fmt(float(checks.det[i])), ", ".join(checks.zero_influence_names(i)) or "∅",
                      ", ".join(checks.indistinguishable_names(i)) or "∅")
    console.print(table)
    console.print(f"global verdict: {record.global_verdict}", highlight=False)
    console.print(f"failing steps: {', '.join(map(str, record.failing_steps)) or 'none'}", highlight=False)
    for message in record.messages():
        console.print(f"• {message}", highlight=False, soft_wrap=True, markup=False)

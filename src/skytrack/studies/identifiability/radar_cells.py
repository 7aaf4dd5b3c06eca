"""Study E2 of spec 002 §6, one-step part: the radar identifiability tables TV8 and TV9.

:func:`radar_case` builds the model (``ct-omega`` R2 or ``ca-accel`` R3, sensor biases appended as
random-walk parameters, R4 ``with_bias``) and the measurement (pos, ṙ, polar and their unions,
sensor at the origin) of one radar set-up; a bias whose channel is not measured stays in the model
with no measurement row acting on it (an exactly zero column of S: the culprit case "range-rate
bias with position-only measurements").  The same builder serves the trajectory study
(:mod:`~.radar_setups`).

* TV8 (R4, R5): p = (30 km, 0), radial v = (−200, 0) m/s or tangential v = (0, 200) m/s, T = 1 s,
  V_η = diag(50², 50², 1²); every (parameters, geometry, set) cell decided by
  :func:`skytrack.analysis.identifiability_along.check_along` on the two states x(k−1), φ(x(k−1)),
  next to the spec's table (verdict, κ at 1 % relative, Z, D, m < p); and TV8's polar variant
  ((r, az) with σ_r = 50 m, σ_az = 0.1° in place of (x, y), sets without b_x: same decision, κ ± 4 %).
* TV9 (R8 full state, G3): (x, y, v_x, v_y, a_x, a_y, b_x) with R3 dynamics over N_w = 10 steps,
  ``unknown="all"``: radar pos alone cannot separate x from b_x, Doppler makes it only weak
  (κ ≈ 2.7·10⁻⁴), an unbiased second position source ("ADS-B", σ = 10 m) makes it identifiable
  (κ ≈ 0.049).  H is the stack of the radar measurement's Jacobian and the unbiased position rows
  along the true track; the decision is :func:`~skytrack.analysis.identifiability_sequence.check_sequence`.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

from skytrack.analysis.identifiability_along import check_along, linearise_along
from skytrack.analysis.identifiability_sequence import check_sequence
from skytrack.models.augmented import AugmentedModel, ca_accel, ct_omega
from skytrack.models.augmented_measurements import CHANNEL_UNITS, AugmentedMeasurement, measurement_for
from skytrack.studies.identification.common import Check

I, W, N = "identifiable", "weak", "not_identifiable"
MEASUREMENT_SETS = {"pos": ("pos",), "rdot": ("rdot",), "pos+rdot": ("pos", "rdot"),
                    "polar": ("polar",), "polar+rdot": ("polar", "rdot")}
#: parameter set label → (model kind, bias channels)
PARAMETER_SETS = {
    "omega": ("omega", ()),
    "omega,b_rdot": ("omega", ("rdot",)),
    "ax,ay": ("accel", ()),
    "ax,ay,b_x": ("accel", ("x",)),
    "ax,ay,b_rdot": ("accel", ("rdot",)),
}
TV8_P0 = (30_000.0, 0.0)
TV8_VELOCITY = {"radial": (-200.0, 0.0), "tangential": (0.0, 200.0)}
TV8_SIGMA = {"x": 50.0, "y": 50.0, "rdot": 1.0, "r": 50.0, "az": math.radians(0.1)}
TV8_KAPPA_RTOL = 0.01
TV8_POLAR_KAPPA_RTOL = 0.04

# spec 002 TV8: (parameters, geometry, set) → (verdict, κ or None when not printed, Z, D, m < p)
TV8_TABLE = {
    ("omega", "radial", "pos"): (I, 1.0, (), (), False),
    ("omega", "radial", "rdot"): (N, 0.0, ("omega",), (), False),
    ("omega", "radial", "pos+rdot"): (I, 1.0, (), (), False),
    ("omega", "tangential", "pos"): (I, 1.0, (), (), False),
    ("omega", "tangential", "rdot"): (I, 1.0, (), (), False),
    ("omega", "tangential", "pos+rdot"): (I, 1.0, (), (), False),
    ("omega,b_rdot", "radial", "pos"): (N, 0.0, ("b_rdot",), (), False),
    ("omega,b_rdot", "radial", "rdot"): (N, 0.0, ("omega",), (), True),
    ("omega,b_rdot", "radial", "pos+rdot"): (I, 1.0, (), (), False),
    ("omega,b_rdot", "tangential", "pos"): (N, 0.0, ("b_rdot",), (), False),
    ("omega,b_rdot", "tangential", "rdot"): (N, None, (), ("omega", "b_rdot"), True),
    ("omega,b_rdot", "tangential", "pos+rdot"): (W, 0.005000, (), ("omega", "b_rdot"), False),
    ("ax,ay", "radial", "pos"): (I, 1.0, (), (), False),
    ("ax,ay", "radial", "rdot"): (N, 0.0, ("ay",), (), True),
    ("ax,ay", "radial", "pos+rdot"): (I, 1.0, (), (), False),
    ("ax,ay", "tangential", "pos"): (I, 1.0, (), (), False),
    ("ax,ay", "tangential", "rdot"): (N, None, (), ("ax", "ay"), True),
    ("ax,ay", "tangential", "pos+rdot"): (I, 0.414254, (), (), False),
    ("ax,ay,b_x", "radial", "pos"): (N, None, (), ("ax", "b_x"), True),
    ("ax,ay,b_x", "radial", "rdot"): (N, 0.0, ("ay", "b_x"), (), True),
    ("ax,ay,b_x", "radial", "pos+rdot"): (I, 0.990050, (), (), False),
    ("ax,ay,b_x", "tangential", "pos"): (N, None, (), ("ax", "b_x"), True),
    ("ax,ay,b_x", "tangential", "rdot"): (N, 0.0, ("b_x",), ("ax", "ay"), True),
    ("ax,ay,b_x", "tangential", "pos+rdot"): (I, 0.414195, (), (), False),
    ("ax,ay,b_rdot", "radial", "pos"): (N, 0.0, ("b_rdot",), (), True),
    ("ax,ay,b_rdot", "radial", "rdot"): (N, 0.0, ("ay",), ("ax", "b_rdot"), True),
    ("ax,ay,b_rdot", "radial", "pos+rdot"): (W, 0.005000, (), ("ax", "b_rdot"), False),
    ("ax,ay,b_rdot", "tangential", "pos"): (N, 0.0, ("b_rdot",), (), True),
    ("ax,ay,b_rdot", "tangential", "rdot"): (N, None, (), ("ax", "ay", "b_rdot"), True),
    ("ax,ay,b_rdot", "tangential", "pos+rdot"): (W, 0.004370, (), ("ax", "b_rdot"), False),
}

TV9_NAMES = ("x", "y", "v_x", "v_y", "a_x", "a_y", "b_x")
TV9_WINDOW = 10
TV9_SIGMA = {"radar": 50.0, "rdot": 1.0, "adsb": 10.0}
# spec 002 TV9: set → (verdict, κ (≈, absolute tolerance) or None, D)
TV9_TABLE = {
    "radar pos": (N, None, ("x", "b_x")),
    "radar pos + rdot": (W, (2.7e-4, 5e-6), ("x", "b_x")),
    "radar pos + ADS-B pos": (I, (0.049, 5e-4), ()),
}


def radar_case(kind: str, biases=(), kinds=("pos",)) -> tuple[AugmentedModel, AugmentedMeasurement]:
    """Model and measurement of one radar set-up: ``kind`` "omega" (ct-omega) or "accel" (ca-accel),
    bias ``channels`` appended in order, measurement ``kinds`` (sensor at the origin)."""
    base = ct_omega() if kind == "omega" else ca_accel()
    measurement = measurement_for(base, kinds)
    for channel in biases:
        if channel in measurement.channels:
            measurement = measurement.with_bias(channel)
        else:  # the bias stays in the model; no measurement row acts on it
            measurement = replace(measurement, state_dim=measurement.state_dim + 1)
    model = base.with_parameters([f"b_{c}" for c in biases], [CHANNEL_UNITS[c] for c in biases],
                                 [1e-6] * len(biases)) if biases else base
    return model, measurement


def noise_covariance(measurement: AugmentedMeasurement, sigma: dict) -> np.ndarray:
    """V_η = diag(σ_c²) over the measurement's channels."""
    return np.diag([sigma[c] ** 2 for c in measurement.channels])


def _names(checks, i, which) -> tuple[str, ...]:
    return tuple(checks.zero_influence_names(i) if which == "Z" else checks.indistinguishable_names(i))


def tv8_table(measurement_sets=("pos", "rdot", "pos+rdot"), polar: bool = False) -> pd.DataFrame:
    """Every TV8 cell: computed verdict, κ, Z, D, m < p, the R6 messages, and the spec's values with a match flag.

    ``polar``: TV8's polar variant — (r, az) with σ_r = 50 m, σ_az = 0.1° in place of (x, y), for the
    cells with a position channel and no b_x; same verdict, Z, D expected, κ within 4 %.
    """
    rows = []
    kappa_rtol = TV8_POLAR_KAPPA_RTOL if polar else TV8_KAPPA_RTOL
    for (parameters, geometry, set_name), expected in TV8_TABLE.items():
        if set_name not in measurement_sets or (polar and ("pos" not in set_name or "b_x" in parameters)):
            continue
        kind, biases = PARAMETER_SETS[parameters]
        if polar:
            set_name = set_name.replace("pos", "polar")
        model, measurement = radar_case(kind, biases, MEASUREMENT_SETS[set_name])
        start = np.zeros(model.dim)
        start[:4] = (*TV8_P0, *TV8_VELOCITY[geometry])
        record = check_along(model, measurement, np.stack([start, model.phi(start, 1.0)]), 1.0,
                             noise_cov=noise_covariance(measurement, TV8_SIGMA))
        checks = record.checks
        verdict, kappa, zero, indistinguishable, fewer = expected
        k = float(checks.kappa[0])
        kappa_ok = (k == 0.0) if kappa == 0.0 else (kappa is None or abs(k - kappa) <= kappa_rtol * kappa)
        found = (checks.verdicts[0], _names(checks, 0, "Z"), _names(checks, 0, "D"), bool(checks.fewer_channels[0]))
        rows.append({"parameters": parameters, "geometry": geometry, "set": set_name,
                     "verdict": found[0], "kappa": k, "Z": ",".join(found[1]), "D": ",".join(found[2]),
                     "m_lt_p": found[3], "expected_verdict": verdict,
                     "expected_kappa": np.nan if kappa is None else kappa,
                     "expected_Z": ",".join(zero), "expected_D": ",".join(indistinguishable), "expected_m_lt_p": fewer,
                     "matches": found == (verdict, zero, indistinguishable, fewer) and kappa_ok,
                     "messages": " | ".join(checks.messages(0))})
    return pd.DataFrame(rows)


def check_polar(polar: pd.DataFrame) -> list[Check]:
    """TV8's polar claim as one check row: every polar cell has the decision of its (x, y) cell."""
    wrong = polar[~polar["matches"]]
    measured = f"{int(polar['matches'].sum())}/{len(polar)} cells as with (x, y)"
    if len(wrong):
        measured += "; differ: " + "; ".join(f"{r.parameters}/{r.geometry}/{r.set}" for r in wrong.itertuples())
    return [Check("TV8 polar (r, az) instead of (x, y), sets without b_x: same verdict, Z, D; κ ± 4 %",
                  measured, f"{len(polar)}/{len(polar)}", wrong.empty and len(polar) > 0)]


def _tv9_states() -> tuple[AugmentedModel, np.ndarray]:
    model = ca_accel().with_parameters(["b_x"], ["m"], [1e-6])
    states = [np.array([30_000.0, 0.0, 0.0, 200.0, 0.0, 0.0, 0.0])]
    for _ in range(TV9_WINDOW):
        states.append(model.phi(states[-1], 1.0))
    return model, np.stack(states)


def tv9_table() -> pd.DataFrame:
    """TV9: the full state over N_w = 10 steps for radar pos, radar pos + ṙ, radar pos + ADS-B pos."""
    model, states = _tv9_states()
    rows = []
    for label, expected in TV9_TABLE.items():
        kinds = ("pos", "rdot") if "rdot" in label else ("pos",)
        radar = measurement_for(ca_accel(), kinds).with_bias("x")
        H, F = linearise_along(model, radar, states, 1.0)
        sigmas = [TV9_SIGMA["radar"]] * 2 + ([TV9_SIGMA["rdot"]] if "rdot" in label else [])
        if "ADS-B" in label:
            adsb = np.zeros((len(H), 2, model.dim))
            adsb[:, 0, 0] = adsb[:, 1, 1] = 1.0
            H = np.concatenate([H, adsb], axis=1)
            sigmas += [TV9_SIGMA["adsb"]] * 2
        record = check_sequence(H, F, unknown="all", names=TV9_NAMES, noise_cov=np.diag(np.square(sigmas)),
                                window=TV9_WINDOW)
        checks = record.checks
        verdict, kappa, indistinguishable = expected
        k = float(checks.kappa[0])
        kappa_ok = kappa is None or abs(k - kappa[0]) <= kappa[1]
        found_d = _names(checks, 0, "D")
        rows.append({"set": label, "verdict": checks.verdicts[0], "kappa": k, "D": ",".join(found_d),
                     "Z": ",".join(_names(checks, 0, "Z")), "expected_verdict": verdict,
                     "expected_kappa": np.nan if kappa is None else kappa[0],
                     "expected_D": ",".join(indistinguishable),
                     "matches": checks.verdicts[0] == verdict and found_d == indistinguishable and kappa_ok,
                     "messages": " | ".join(checks.messages(0))})
    return pd.DataFrame(rows)

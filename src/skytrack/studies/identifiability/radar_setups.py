"""Study E2 of spec 002 §6, set-up part: which radar parameters are identifiable along E3's track.

For the parameters {ω} of ``ct-omega`` (R2) and {a_x, a_y} of ``ca-accel`` (R3), alone and with
sensor biases appended (R4 ``with_bias`` on x, y, ṙ), under the measurement sets pos, ṙ, pos+ṙ,
polar and polar+ṙ (σ_pos = σ_r = 20 m, σ_ṙ = 0.5 m/s, σ_az = 0.1°), every interval of the E3
trajectory is decided by :func:`skytrack.analysis.identifiability_along.check_along` (R10, R5 per
step) and summarised by R7: per-step verdict counts, the global verdict (the worst local one),
the parameters that are determined at every step (never in Z or D), and the culprits with their
step counts (Z: no influence; D: indistinguishable; ``m < p``) and one R6 message.

ca-accel states along the CT truth carry the true centripetal acceleration a = ω (−v_y, v_x); bias
states are 0.  A bias on a channel that the set does not measure stays in the model with no row
acting on it, which is the built culprit "range-rate bias with position-only measurements".

:data:`CULPRIT_CASES` lists the cases built to have a culprit (and two built not to), with the
culprit that must be named; :func:`check_culprits` turns them into pass/fail rows.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skytrack.analysis.identifiability_along import check_along
from skytrack.studies.identifiability.radar_cells import MEASUREMENT_SETS, noise_covariance, radar_case
from skytrack.studies.identifiability.radar_track import TRACK_SIGMA, truth_states
from skytrack.studies.identification.common import Check

#: parameter set label → (model kind, bias channels)
SETUPS = {
    "omega": ("omega", ()),
    "omega,b_x": ("omega", ("x",)),
    "omega,b_x,b_y": ("omega", ("x", "y")),
    "omega,b_rdot": ("omega", ("rdot",)),
    "ax,ay": ("accel", ()),
    "ax,ay,b_x": ("accel", ("x",)),
    "ax,ay,b_rdot": ("accel", ("rdot",)),
}
SETUP_SETS = ("pos", "rdot", "pos+rdot", "polar", "polar+rdot")

#: (parameters, set) → (expected global verdict, culprit kind "Z" / "D" / None, culprit names, why)
CULPRIT_CASES = {
    ("omega,b_rdot", "pos"): ("not_identifiable", "Z", ("b_rdot",),
                              "a range-rate bias with position-only measurements has no influence at any step"),
    ("ax,ay,b_x", "pos"): ("not_identifiable", "D", ("ax", "b_x"),
                           "a one-step acceleration and an x-position bias move x alike (and m = 2 < p = 3)"),
    ("omega,b_rdot", "pos+rdot"): ("weak", "D", ("omega", "b_rdot"),
                                   "in tangential flight a turn and a Doppler bias change ṙ alike (TV8: κ = 0.005)"),
    ("omega,b_x", "pos"): ("weak", "D", ("omega", "b_x"),
                           "heading north (v_x ≈ 0 after turn 1) a turn and an x bias move x alike"),
    ("omega", "pos"): ("identifiable", None, (), "position alone identifies ω at every step (σ_χ = 11.46°/s)"),
    ("omega", "pos+rdot"): ("identifiable", None, (), "position + Doppler identifies ω at every step"),
}


def setup_states(kind: str, n_biases: int, T: float = 1.0) -> np.ndarray:
    """The E3 truth in the set-up's state layout (ct-omega or ca-accel, then zero biases)."""
    _, states = truth_states(T)
    if kind == "accel":
        omega, velocity = states[:, 4:5], states[:, 2:4]
        acceleration = omega * np.stack([-velocity[:, 1], velocity[:, 0]], axis=1)
        states = np.concatenate([states[:, :4], acceleration], axis=1)
    return np.concatenate([states, np.zeros((len(states), n_biases))], axis=1)


def _count_text(counts: dict) -> str:
    return ", ".join(f"{name} ({count} steps)" for name, count in counts.items() if count)


def setup_record(parameters: str, set_name: str, T: float = 1.0, window: int = 1):
    """R7 record of one set-up along the E3 track."""
    kind, biases = SETUPS[parameters]
    model, measurement = radar_case(kind, biases, MEASUREMENT_SETS[set_name])
    return check_along(model, measurement, setup_states(kind, len(biases), T), T,
                       noise_cov=noise_covariance(measurement, TRACK_SIGMA), window=window)


def setups_table(T: float = 1.0, window: int = 1, setups=tuple(SETUPS), sets=SETUP_SETS) -> pd.DataFrame:
    """One row per (parameters, measurement set): per-step counts, global verdict, determined parameters,
    culprits (Z, D with step counts, m < p) and the first R6 message."""
    rows = []
    for parameters in setups:
        for set_name in sets:
            record = setup_record(parameters, set_name, T, window)
            checks = record.checks
            verdicts = pd.Series(record.verdicts)
            zero, indistinguishable = record.zero_influence_count, record.indistinguishable_count
            determined = [n for n in checks.names if zero[n] == 0 and indistinguishable[n] == 0]
            messages = record.messages()
            rows.append({"parameters": parameters, "set": set_name, "steps": len(verdicts),
                         "identifiable": int((verdicts == "identifiable").sum()),
                         "weak": int((verdicts == "weak").sum()),
                         "not_identifiable": int((verdicts == "not_identifiable").sum()),
                         "global": record.global_verdict, "determined_every_step": ",".join(determined),
                         "Z_culprits": _count_text(zero), "D_culprits": _count_text(indistinguishable),
                         "m_lt_p": bool(checks.fewer_channels[0]), "kappa_min": float(checks.kappa.min()),
                         "first_message": messages[0] if messages else ""})
    return pd.DataFrame(rows)


def check_culprits(table: pd.DataFrame) -> list[Check]:
    """Each built case: its global verdict, and its culprit named in the counts and in an R6 message."""
    checks = []
    for (parameters, set_name), (verdict, kind, names, why) in CULPRIT_CASES.items():
        row = table[(table["parameters"] == parameters) & (table["set"] == set_name)]
        if row.empty:
            continue
        row = row.iloc[0]
        culprits = row["Z_culprits"] if kind == "Z" else row["D_culprits"] if kind == "D" else ""
        named = all(f"{n} (" in culprits for n in names) and all(n in row["first_message"] for n in names)
        if kind is None:
            passed = row["global"] == verdict and row["first_message"] == ""
            expected = f"{verdict}, no culprit"
        else:
            passed = row["global"] == verdict and named
            expected = f"{verdict}, {kind} names {', '.join(names)}"
        checks.append(Check(f"culprit case {{{parameters}}} / {set_name}: {why}",
                            f"{row['global']}; Z: {row['Z_culprits'] or '—'}; D: {row['D_culprits'] or '—'}; "
                            f"“{row['first_message'] or 'no message'}”", expected, passed))
    return checks

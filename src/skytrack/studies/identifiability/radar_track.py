"""Study E2 of spec 002 §6, trajectory part: one-step precision σ_χ(t) of the turn rate along E3's track.

The E3 truth (sensor at the origin): coordinated turn (R2) from p(0) = (0, 30 km), v(0) = (200, 0) m/s,
ω = 0 on [0, 60) s, +3°/s on [60, 92), 0 on [92, 152), −1.5°/s on [152, 212), 0 on [212, 272]; the
step t_k → t_{k+1} uses ω(t_k) (simulated by :mod:`skytrack.studies.turn_rate.scenario`).  Along it
:func:`skytrack.analysis.identifiability_along.check_along` (R10) decides the parameter ω of
``ct-omega`` on every interval [t_{k−1}, t_k] for the measurement sets pos (σ_pos = 20 m), ṙ
(σ_ṙ = 0.5 m/s) and pos+ṙ, with T = 1 s, and reports σ_χ (R9): the std of the noise-weighted
one-step LS estimate of ω with x(k−1) known.  ψ is the angle between the line of sight u = p/|p|
and the velocity at t_k (where H_k is linearised).

Expected (§6 E2): pos σ_χ constant at σ_pos/(T² v/2) = 11.46°/s (position moves by T²v/2 per rad/s);
ṙ and pos+ṙ ≈ σ_ṙ/(T v sin ψ) = 0.143°/s in tangential flight, rising to ≈ 29°/s (ṙ) and
≈ 10.7°/s (pos+ṙ) at t ≈ 166 s where ψ = 0.3° (the aircraft flies almost along the line of sight,
so a turn hardly changes the range rate).  Tolerances used by :func:`check_track`: 11.46 within 1 %
(and flat within 0.1 %), 0.143 within 5 %, the peak values within 15 %, the peak time within 2 s.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from skytrack.analysis.identifiability_along import check_along
from skytrack.models.augmented import ct_omega
from skytrack.models.augmented_measurements import measurement_for
from skytrack.studies.identification.common import Check, pyplot
from skytrack.studies.turn_rate import scenario

#: E2 observes E3's track with E3's sensor accuracies
SIGMA_POS_M = scenario.SIGMA_POSITION
SIGMA_RDOT_MPS = scenario.SIGMA_RANGE_RATE
#: σ_az of the polar set-ups (not given by §6 E2; TV8's value)
SIGMA_AZ_RAD = math.radians(0.1)
TRACK_SIGMA = {"x": SIGMA_POS_M, "y": SIGMA_POS_M, "rdot": SIGMA_RDOT_MPS, "r": SIGMA_POS_M, "az": SIGMA_AZ_RAD}
TRACK_SETS = {"pos": ("pos",), "rdot": ("rdot",), "pos+rdot": ("pos", "rdot")}

EXPECTED_POS_DEG = 11.46
EXPECTED_TANGENTIAL_DEG = 0.143
EXPECTED_PEAK_DEG = {"rdot": 29.0, "pos+rdot": 10.7}
EXPECTED_PEAK_TIME_S = 166.0
EXPECTED_PEAK_PSI_DEG = 0.3
POS_RTOL = 0.01
POS_FLATNESS = 0.001
TANGENTIAL_RTOL = 0.05
PEAK_RTOL = 0.15
PEAK_TIME_ATOL_S = 2.0
PSI_ATOL_DEG = 0.05
#: the first straight leg [0, 60) s is tangential flight (ψ ≥ 78°)
TANGENTIAL_WINDOW_S = (1.0, 60.0)


def truth_states(T: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Times t_k = kT on [0, 272] s and ct-omega states (x, y, vx, vy, ω(t_k)) of the E3 truth.

    The trajectory is study E3's (:func:`skytrack.studies.turn_rate.scenario.simulate_truth`: the step
    t_k → t_{k+1} turns at ω(t_k)); the ω column is replaced by ω(t_k) because the interval
    [t_k, t_{k+1}] is linearised at x(t_k), whose turn rate is the one that step uses.
    """
    times, states = scenario.simulate_truth(T, rate_at="start")
    states = states.copy()
    states[:, 4] = scenario.turn_rate(times)
    return times, states


def line_of_sight_angle_deg(states: np.ndarray) -> np.ndarray:
    """ψ ∈ [0°, 180°] between u = p/|p| (sensor at the origin) and the velocity."""
    p, v = states[:, :2], states[:, 2:4]
    cosine = np.einsum("ki,ki->k", p, v) / (np.linalg.norm(p, axis=1) * np.linalg.norm(v, axis=1))
    return np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))


def precision_along(T: float = 1.0, window: int = 1) -> tuple[pd.DataFrame, dict]:
    """Per interval k: t_{k−1}, t_k, ψ(t_k), and for pos, ṙ, pos+ṙ the verdict and σ_χ of ω (°/s);
    also the R7 records (one per set)."""
    times, states = truth_states(T)
    model = ct_omega()
    records = {}
    count = len(times) - window
    table = pd.DataFrame({"k": np.arange(1, count + 1), "t_start_s": times[:count], "t_s": times[1:count + 1],
                          "speed_mps": np.linalg.norm(states[1:count + 1, 2:4], axis=1),
                          "psi_deg": line_of_sight_angle_deg(states[1:count + 1]),
                          "omega_true_deg_s": np.degrees(states[:count, 4])})
    for name, kinds in TRACK_SETS.items():
        measurement = measurement_for(model, kinds)
        cov = np.diag([TRACK_SIGMA[c] ** 2 for c in measurement.channels])
        record = check_along(model, measurement, states, T, noise_cov=cov, window=window)
        records[name] = record
        table[f"sigma_{name}_deg_s"] = np.degrees(record.checks.precision[:, 0])
        table[f"verdict_{name}"] = record.verdicts
    speed = table["speed_mps"].to_numpy()
    with np.errstate(divide="ignore"):
        table["sigma_pos_closed_form_deg_s"] = np.degrees(SIGMA_POS_M / (T * T * speed / 2.0))
        table["sigma_rdot_closed_form_deg_s"] = np.degrees(
            SIGMA_RDOT_MPS / (T * speed * np.abs(np.sin(np.radians(table["psi_deg"].to_numpy())))))
    return table, records


def step_summary(table: pd.DataFrame, records: dict, worst: int = 5) -> pd.DataFrame:
    """Per measurement set: verdict counts, global verdict (R7), failing steps, σ_χ range and the worst steps."""
    rows = []
    for name, record in records.items():
        sigma = table[f"sigma_{name}_deg_s"].to_numpy()
        order = np.argsort(-np.nan_to_num(sigma, nan=np.inf))[:worst]
        verdicts = pd.Series(record.verdicts)
        rows.append({"set": name, "steps": len(verdicts),
                     "identifiable": int((verdicts == "identifiable").sum()), "weak": int((verdicts == "weak").sum()),
                     "not_identifiable": int((verdicts == "not_identifiable").sum()),
                     "global": record.global_verdict, "failing_steps": record.failing_steps,
                     "sigma_min_deg_s": float(np.nanmin(sigma)), "sigma_median_deg_s": float(np.nanmedian(sigma)),
                     "sigma_max_deg_s": float(np.nanmax(sigma)),
                     "worst_steps": ", ".join(f"t={table['t_s'].iloc[i]:.0f} s: {sigma[i]:.3g}°/s "
                                              f"(ψ={table['psi_deg'].iloc[i]:.2f}°)" for i in order)})
    return pd.DataFrame(rows)


def check_track(table: pd.DataFrame) -> list[Check]:
    """The §6 E2 expectations on σ_χ(t) with the tolerances of the module docstring."""
    checks = []
    pos = table["sigma_pos_deg_s"]
    pos_mean = float(pos.mean())
    spread = float((pos.max() - pos.min()) / pos_mean)
    checks.append(Check("pos σ_χ constant = σ_pos/(T²v/2)", f"{pos.min():.4f} … {pos.max():.4f} °/s",
                        f"{EXPECTED_POS_DEG} °/s ± {POS_RTOL:.0%}, flat within {POS_FLATNESS:.1%}",
                        abs(pos_mean - EXPECTED_POS_DEG) <= POS_RTOL * EXPECTED_POS_DEG and spread <= POS_FLATNESS))
    straight = table[(table["t_s"] >= TANGENTIAL_WINDOW_S[0]) & (table["t_s"] < TANGENTIAL_WINDOW_S[1])]
    for name in ("rdot", "pos+rdot"):
        value = float(straight[f"sigma_{name}_deg_s"].min())
        checks.append(Check(f"{name} σ_χ in tangential flight (t < 60 s, ψ = {straight['psi_deg'].max():.1f}°)",
                            f"{value:.4f} °/s", f"{EXPECTED_TANGENTIAL_DEG} °/s ± {TANGENTIAL_RTOL:.0%}",
                            abs(value - EXPECTED_TANGENTIAL_DEG) <= TANGENTIAL_RTOL * EXPECTED_TANGENTIAL_DEG))
    for name, wanted in EXPECTED_PEAK_DEG.items():
        column = table[f"sigma_{name}_deg_s"]
        i = int(column.idxmax())
        peak, t_peak, psi = float(column.iloc[i]), float(table["t_s"].iloc[i]), float(table["psi_deg"].iloc[i])
        checks.append(Check(f"{name} σ_χ peak where ψ is smallest",
                            f"{peak:.2f} °/s at t = {t_peak:.0f} s (interval [{t_peak - 1:.0f}, {t_peak:.0f}]), "
                            f"ψ = {psi:.3f}°",
                            f"≈ {wanted} °/s ± {PEAK_RTOL:.0%} at t ≈ {EXPECTED_PEAK_TIME_S:.0f} ± "
                            f"{PEAK_TIME_ATOL_S:.0f} s, ψ = {EXPECTED_PEAK_PSI_DEG}°",
                            abs(peak - wanted) <= PEAK_RTOL * wanted
                            and abs(t_peak - EXPECTED_PEAK_TIME_S) <= PEAK_TIME_ATOL_S
                            and abs(psi - EXPECTED_PEAK_PSI_DEG) <= PSI_ATOL_DEG))
    return checks


def plot_track(table: pd.DataFrame):
    """Top: σ_χ(t) of ω for pos, ṙ, pos+ṙ (log scale) with the closed forms; bottom: ψ(t) and ω(t)."""
    plt = pyplot()
    fig, (ax_sigma, ax_psi) = plt.subplots(2, 1, figsize=(10.0, 7.5), sharex=True,
                                           gridspec_kw={"height_ratios": [2, 1]})
    t = table["t_s"]
    ax_sigma.plot(t, table["sigma_pos_deg_s"], label="pos (σ_pos = 20 m)", color="tab:blue")
    ax_sigma.plot(t, table["sigma_rdot_deg_s"], label="ṙ (σ_ṙ = 0.5 m/s)", color="tab:orange")
    ax_sigma.plot(t, table["sigma_pos+rdot_deg_s"], label="pos + ṙ", color="tab:green")
    ax_sigma.plot(t, table["sigma_rdot_closed_form_deg_s"], label="σ_ṙ/(T v sin ψ)", color="black",
                  linestyle=":", linewidth=1.0)
    ax_sigma.axhline(EXPECTED_POS_DEG, color="tab:blue", linestyle="--", linewidth=0.8,
                     label=f"σ_pos/(T²v/2) = {EXPECTED_POS_DEG}°/s")
    ax_sigma.set_yscale("log")
    ax_sigma.set_ylabel("σ_χ of ω [°/s]")
    ax_sigma.set_title("E2: one-step precision of the turn rate along the E3 track (R9, T = 1 s)")
    ax_sigma.legend(fontsize="small", loc="upper left")
    ax_sigma.grid(True, which="both", alpha=0.3)
    ax_psi.plot(t, table["psi_deg"], color="tab:purple", label="ψ (line of sight vs velocity)")
    ax_psi.set_ylabel("ψ [°]")
    ax_psi.set_xlabel("time t_k [s]")
    ax_psi.set_title("angle ψ between line of sight and velocity; truth ω on the right axis")
    ax_omega = ax_psi.twinx()
    ax_omega.step(t, table["omega_true_deg_s"], where="post", color="tab:gray", linestyle="--", label="truth ω on [t_k−1, t_k]")
    ax_omega.set_ylabel("ω [°/s]")
    lines = ax_psi.get_legend_handles_labels()
    more = ax_omega.get_legend_handles_labels()
    ax_psi.legend(lines[0] + more[0], lines[1] + more[1], fontsize="small", loc="upper right")
    ax_psi.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig

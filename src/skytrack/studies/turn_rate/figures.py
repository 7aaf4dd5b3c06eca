"""Figures of spec 002 §6 E3/E4 (``skytrack study turn-rate-adaptive``): one PNG per (T, measurement set).

Four panels: ω̂(t) of the first run of every configuration against the true turn rate (the IMM's
Σ μ_j ω_j where it was run); the median √V̂_w(t) over the kept runs with the floor σ_min and the
ceiling σ_max of R14 (A5.5); ω-RMSE(t) and position RMSE(t) over the kept runs.  Shaded bands mark
the two turns.  Angles in °/s, positions in m, time in s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skytrack.studies.fuzzy.common import pyplot, save_figure
from skytrack.studies.turn_rate import scenario as sc

LABELS = {c.key: c.label for c in sc.CONFIGURATIONS} | {"imm": "IMM cv-ct (pos)"}
#: axes titles, in panel order (tests find the panels by them)
PANEL_TITLES = ("ω̂(t), first run", "median √V̂_w(t)", "ω-RMSE(t)", "position RMSE(t)")


def figure_name(T: float, measurement: str, q_accel: float) -> str:
    return f"turn_rate_T{T:g}_{measurement.replace('+', '_')}_qa{q_accel:g}.png"


def setup_figure(summaries, T: float, measurement: str, q_accel: float, path: Path) -> Path:
    """Write the four panels of one setup as PNG (``summaries``: :class:`~.metrics.Summary` of that setup)."""
    return save_figure(draw_setup(summaries, T, measurement, q_accel), path)


def draw_setup(summaries, T: float, measurement: str, q_accel: float):
    """The open matplotlib figure of :func:`setup_figure` (tests read its line data)."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), sharex=True)
    ax_omega, ax_sigma, ax_rmse, ax_pos = axes.ravel()
    first = summaries[0].curves
    times = first["times"]
    ax_omega.plot(times, first["omega_true"], color="black", lw=2.0, label="truth")
    for s in summaries:
        c = s.curves
        label = LABELS.get(s.key, s.key)
        ax_omega.plot(c["times"], c["omega_hat_first_run"], lw=1.0, label=label)
        if np.isfinite(c["median_sigma_w_t"]).any():
            ax_sigma.plot(c["times"], c["median_sigma_w_t"], lw=1.0, label=label)
        ax_rmse.plot(c["times"], c["omega_rmse_t"], lw=1.0, label=label)
        ax_pos.plot(c["times"], c["position_rmse_t"], lw=1.0, label=label)
    ax_sigma.axhline(sc.PRESET_SIGMA_MIN / sc.DEG, color="grey", ls="--", lw=1.0, label="floor σ_min")
    ax_sigma.axhline(sc.PRESET_SIGMA_MAX / sc.DEG, color="grey", ls=":", lw=1.0, label="ceiling σ_max")
    ax_sigma.set_yscale("log")
    units = ("ω [°/s]", "√V̂_w [°/s per step]", "ω-RMSE [°/s]", "position RMSE [m]")
    for ax, title, unit in zip(axes.ravel(), PANEL_TITLES, units):
        for start, end, omega in sc.TURN_SCHEDULE:
            if omega != 0.0:
                ax.axvspan(start, end, color="orange", alpha=0.12)
        ax.set_title(title)
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in axes[1]:
        ax.set_xlabel("time t [s]")
    fig.suptitle(f"turn-rate-adaptive (spec 002 E3/E4): T = {T:g} s, {sc.MEASUREMENT_LABELS[measurement]}, "
                 f"q_a = {q_accel:g} m²/s³, {summaries[0].runs} runs (turns shaded)")
    fig.tight_layout()
    return fig

"""Study E2 of spec 002 §6 (``skytrack study ident-radar``): which parameters radar data identify.

Puts together the one-step tables TV8 and TV9 (:mod:`~.radar_cells`), σ_χ(t) of the turn rate and
ψ(t) along the E3 track with per-step and global verdicts (:mod:`~.radar_track`) and the set-up table
with culprits (:mod:`~.radar_setups`), checks every expectation (§5 TV8, TV9; §6 E2) and writes

* ``ident_radar_track.csv`` — per interval: t, ψ, ω, σ_χ and verdict for pos, ṙ, pos+ṙ;
* ``ident_radar_steps.csv`` — per measurement set: verdict counts, global verdict, worst steps;
* ``ident_radar_setups.csv`` — per (parameters, set): counts, global verdict, culprits, R6 message;
* ``ident_radar_tv8.csv``, ``ident_radar_tv8_polar.csv``, ``ident_radar_tv9.csv`` — computed cells next
  to the spec's (polar: (r, az) in place of (x, y) for the parameter sets without b_x);
* ``ident_radar.png`` — σ_χ(t) (log), κ(t) of two bias set-ups (log), ψ(t) with ω(t);
* ``ident_radar_summary.json`` — options, results, checks.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.analysis.identifiability import TAU_WEAK
from skytrack.studies.identifiability import radar_cells, radar_setups, radar_track
from skytrack.studies.identification.common import Check, pyplot, save_figure, write_summary

#: the set-ups whose margin κ(t) is drawn (a culprit appears where κ dips below τ_weak)
KAPPA_PANEL = (("omega,b_rdot", "pos+rdot"), ("omega,b_x", "pos"), ("omega", "pos+rdot"))
NAMES = {"csv": "ident_radar_track.csv", "steps": "ident_radar_steps.csv", "setups": "ident_radar_setups.csv",
         "tv8": "ident_radar_tv8.csv", "tv8_polar": "ident_radar_tv8_polar.csv", "tv9": "ident_radar_tv9.csv", "png": "ident_radar.png",
         "json": "ident_radar_summary.json"}


def check_tables(tv8: pd.DataFrame, tv9: pd.DataFrame) -> list[Check]:
    """TV8 (30 cells) and TV9 (3 rows) against the spec's tables (the polar variant: radar_cells.check_polar)."""
    checks = []
    for label, table in (("TV8 cells (verdict, κ ± 1 %, Z, D, m < p)", tv8), ("TV9 rows (verdict, κ, D)", tv9)):
        wrong = table[~table["matches"]]
        keys = ["parameters", "geometry", "set"] if "geometry" in table else ["set"]
        measured = f"{int(table['matches'].sum())}/{len(table)} match"
        if len(wrong):
            measured += "; differ: " + "; ".join("/".join(str(r[k]) for k in keys) for _, r in wrong.iterrows())
        checks.append(Check(label, measured, f"{len(table)}/{len(table)} match", wrong.empty))
    return checks


def kappa_tracks(T: float, window: int) -> pd.DataFrame:
    """κ(t) per interval for the set-ups of :data:`KAPPA_PANEL`."""
    frames = []
    for parameters, set_name in KAPPA_PANEL:
        record = radar_setups.setup_record(parameters, set_name, T, window)
        frames.append(pd.DataFrame({"setup": f"{{{parameters}}} / {set_name}", "k": record.steps,
                                    "t_s": np.asarray(record.steps) * T, "kappa": record.checks.kappa,
                                    "verdict": record.verdicts}))
    return pd.concat(frames, ignore_index=True)


def plot_radar(track: pd.DataFrame, kappa: pd.DataFrame):
    """σ_χ(t) and ψ(t) from :func:`radar_track.plot_track` plus a κ(t) panel between them."""
    fig = radar_track.plot_track(track)
    ax_sigma, ax_psi = fig.axes[:2]
    fig.set_size_inches(10.0, 10.0)
    grid = fig.add_gridspec(3, 1, height_ratios=[2, 1.3, 1])
    ax_sigma.set_subplotspec(grid[0])
    ax_psi.set_subplotspec(grid[2])
    for twin in fig.axes[2:]:
        twin.set_subplotspec(grid[2])
    ax_kappa = fig.add_subplot(grid[1], sharex=ax_sigma)
    colours = pyplot().get_cmap("tab10").colors[4:]
    for colour, (setup, group) in zip(colours, kappa.groupby("setup", sort=False)):
        ax_kappa.plot(group["t_s"], group["kappa"], color=colour, label=setup)
    ax_kappa.axhline(TAU_WEAK, color="tab:red", linestyle="--", linewidth=0.8, label=f"τ_weak = {TAU_WEAK:g} (R5)")
    ax_kappa.set_yscale("log")
    ax_kappa.set_ylabel("κ [dimensionless]")
    ax_kappa.set_xlabel("time t_k [s]")
    ax_kappa.set_title("margin κ(t) with sensor biases: below τ_weak the parameters are weakly identifiable (D)")
    ax_kappa.legend(fontsize="small", loc="lower left")
    ax_kappa.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def run_radar(out_dir: Path, T: float = 1.0, window: int = 1) -> dict:
    """E2: every table and check; writes the CSVs, the PNG and the JSON summary to ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tv8 = radar_cells.tv8_table()
    tv9 = radar_cells.tv9_table()
    polar = radar_cells.tv8_table(polar=True)
    track, records = radar_track.precision_along(T, window)
    steps = radar_track.step_summary(track, records)
    setups = radar_setups.setups_table(T, window)
    kappa = kappa_tracks(T, window)
    checks = check_tables(tv8, tv9)
    checks += radar_cells.check_polar(polar)
    if T == 1.0 and window == 1:  # §6 E2's numbers and the built cases are for the one-step check at T = 1 s
        checks += radar_track.check_track(track)
        checks += radar_setups.check_culprits(setups)
    paths = {key: out_dir / name for key, name in NAMES.items()}
    track.to_csv(paths["csv"], index=False, float_format="%.10g")
    steps.to_csv(paths["steps"], index=False, float_format="%.10g")
    setups.to_csv(paths["setups"], index=False, float_format="%.10g")
    tv8.to_csv(paths["tv8"], index=False, float_format="%.10g")
    polar.to_csv(paths["tv8_polar"], index=False, float_format="%.10g")
    tv9.to_csv(paths["tv9"], index=False, float_format="%.10g")
    save_figure(plot_radar(track, kappa), paths["png"])
    results = {"steps": steps.to_dict(orient="records"),
               "setups": setups.to_dict(orient="records"),
               "tv8_matches": int(tv8["matches"].sum()), "tv9": tv9.to_dict(orient="records")}
    options = {"T_s": T, "window": window, "sigma_pos_m": radar_track.SIGMA_POS_M,
               "sigma_rdot_mps": radar_track.SIGMA_RDOT_MPS, "sigma_az_deg": float(np.degrees(radar_track.SIGMA_AZ_RAD))}
    write_summary(paths["json"], "ident-radar", options, results, checks)
    return {"tv8": tv8, "tv8_polar": polar, "tv9": tv9, "track": track, "steps": steps, "setups": setups, "kappa": kappa,
            "checks": checks, "paths": paths, "results": results, "options": options}

"""Study E2 of spec 003 §6: decision regions along a line (the TV9 configuration; R10, D4, D5).

Tracks A and B have predicted measurements that differ only in range, by 300 m; S_A =
diag(50², σ_α², σ_ε², σ_V²) and S_B = 9 S_A.  A plot at range offset x from A (x − 300 from
B, zero residual otherwise) is decided by three rules, one horizontal band each:

* ``ml`` — maximum likelihood with the χ² gate (new only when no track gates, R10);
* ``fuzzy`` without features — every feature factor 1 (identical to ``nn``);
* ``fuzzy`` with features — plot foe / "5670", A friend / "1234", B foe / "5670", the paper's
  tables (15), (16).

The boundaries are found by bisection to 1e-6 m (reported to 1e-3 m) and compared with
their closed forms (TV9): A's gate ±50√γ, B's gate 300 ∓ 150√γ, the ``ml`` crossing (the
positive root of (x/50)² − ((x − 300)/150)² = 8 ln 3), the ``fuzzy`` crossings −150 and 75,
and B's feature-shrunk gate 300 ∓ 150√(γ + 2 ln 0.72).  Both claims of the paper show:
ML favours the tight track (A's region reaches 155.8 m instead of 75 m), and the features
override geometry (A disappears).

:func:`run_regions` writes ``fuzzy_regions.csv`` (one row per boundary) and ``fuzzy_regions.png``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.association.features import FOE, FRIEND, PAPER_TABLES, UNIT_TABLES
from skytrack.association.identity_rules import NEW, RuleConfig, coordinate_terms, decide_greedy, gate_gamma, new_object_score, score_pairs
from skytrack.studies.fuzzy.common import Check, pyplot, save_figure

RANGE_SEPARATION_M = 300.0
#: standard deviations of S_A (range m, azimuth rad, elevation rad, radial velocity m/s); S_B = 9 S_A
SIGMA_A = (50.0, 0.004, 0.004, 2.0)
SCALE_B = 3.0
X_RANGE_M = (-700.0, 1000.0)
GRID_STEP_M = 0.5
BISECTION_TOLERANCE_M = 1e-6
CODE_1234, CODE_5670 = int("1234", 8), int("5670", 8)
#: band -> (label, rule, tables, plot's (status, code) or None)
BANDS = {
    "ml": ("ml", "ml", UNIT_TABLES, None),
    "fuzzy": ("fuzzy, no features", "fuzzy", UNIT_TABLES, None),
    "fuzzy-features": ("fuzzy, with features", "fuzzy", PAPER_TABLES, (FOE, CODE_5670)),
}
CHOICE_NAMES = {0: "A", 1: "B", NEW: "new"}
#: TV9's boundaries (left choice, right choice, x [m]) to the spec's 1e-3 m
TV9_BOUNDARIES = {
    "ml": [("new", "B", -246.558), ("B", "A", -182.186), ("A", "B", 155.826), ("B", "new", 846.558)],
    "fuzzy": [("new", "B", -246.558), ("B", "A", -150.0), ("A", "B", 75.0), ("B", "new", 846.558)],
    "fuzzy-features": [("new", "B", -232.863), ("B", "new", 832.863)],
}
TV9_TOLERANCE_M = 1e-3
CSV_NAME = "fuzzy_regions.csv"
PNG_NAME = "fuzzy_regions.png"
CHOICE_COLOURS = {"A": "tab:blue", "B": "tab:orange", "new": "lightgrey"}
CHOICE_LABELS = {"A": "track A (friend 1234, σ_D 50 m)", "B": "track B (foe 5670, σ_D 150 m)", "new": "new object"}


def choices_along_line(band: str, x: np.ndarray, p_gate: float = 0.99) -> np.ndarray:
    """Choice per plot offset ``x`` [m]: 0 (A), 1 (B) or :data:`NEW`, by the band's rule (greedy, R12 ties)."""
    _, rule, tables, plot_features = BANDS[band]
    x = np.asarray(x, dtype=float)
    S_A = np.diag(np.square(SIGMA_A))
    nu = np.zeros((len(x), 2, 4))
    nu[:, 0, 0] = x
    nu[:, 1, 0] = x - RANGE_SEPARATION_M
    S = np.broadcast_to(np.stack([S_A, SCALE_B**2 * S_A]), (len(x), 2, 4, 4)).reshape(-1, 4, 4)
    d2, logdet = coordinate_terms(nu.reshape(-1, 4), S)
    config = RuleConfig(rule=rule, mode="greedy", p_gate=p_gate, tables=tables)
    ln_g = ln_n = None
    if plot_features is not None:
        track_iff = np.tile([FRIEND, FOE], len(x))
        track_code = np.tile([CODE_1234, CODE_5670], len(x))
        ln_g = tables.log_mu_g(track_iff, np.full(2 * len(x), plot_features[0]))
        ln_n = tables.log_mu_n(track_code, np.full(2 * len(x), plot_features[1]))
    scores = score_pairs(config, d2, logdet, 4, ln_g, ln_n)
    return decide_greedy(scores.score.reshape(-1, 2), scores.hypothesis.reshape(-1, 2),
                         new_object_score(config, np.full(len(x), 4)))


def find_boundaries(band: str, p_gate: float = 0.99, x_range=X_RANGE_M, step: float = GRID_STEP_M,
                    tolerance: float = BISECTION_TOLERANCE_M) -> pd.DataFrame:
    """Changes of choice along ``x_range``: a grid scan, then one vectorised bisection of all
    brackets together.  Rows ``left, right, x_m`` in increasing x."""
    x = np.arange(x_range[0], x_range[1] + 0.5 * step, step)
    choice = choices_along_line(band, x, p_gate)
    where = np.flatnonzero(choice[1:] != choice[:-1])
    lo, hi = x[where], x[where + 1]
    left, right = choice[where], choice[where + 1]
    while lo.size and np.max(hi - lo) > tolerance:
        mid = 0.5 * (lo + hi)
        same_as_left = choices_along_line(band, mid, p_gate) == left
        lo, hi = np.where(same_as_left, mid, lo), np.where(same_as_left, hi, mid)
    return pd.DataFrame({"left": [CHOICE_NAMES[int(c)] for c in left], "right": [CHOICE_NAMES[int(c)] for c in right],
                         "x_m": 0.5 * (lo + hi)})


def closed_form_boundaries(p_gate: float = 0.99) -> dict[str, list[float]]:
    """TV9's boundaries from their closed forms, per band, in increasing x."""
    gamma = gate_gamma(4, p_gate)
    sigma_b = SCALE_B * SIGMA_A[0]
    gate_b = (RANGE_SEPARATION_M - sigma_b * math.sqrt(gamma), RANGE_SEPARATION_M + sigma_b * math.sqrt(gamma))
    gate_a = SIGMA_A[0] * math.sqrt(gamma)
    # (x/50)^2 - ((x - 300)/150)^2 = c  <=>  8 x^2 + 600 x - 90000 - 22500 c = 0 (S_B = 9 S_A)
    a, b, c0 = SCALE_B**2 - 1.0, 2.0 * RANGE_SEPARATION_M, -RANGE_SEPARATION_M**2
    scale = sigma_b**2

    def positive_root(c):
        return (-b + math.sqrt(b * b - 4 * a * (c0 - scale * c))) / (2 * a)

    def negative_root(c):
        return (-b - math.sqrt(b * b - 4 * a * (c0 - scale * c))) / (2 * a)

    ml_crossing = positive_root(4.0 * math.log(SCALE_B**2))  # ln det S_B - ln det S_A = 8 ln 3
    shrunk = sigma_b * math.sqrt(gamma + 2.0 * math.log(0.8 * 0.9))
    return {
        "ml": [gate_b[0], -gate_a, ml_crossing, gate_b[1]],
        "fuzzy": [gate_b[0], negative_root(0.0), positive_root(0.0), gate_b[1]],
        "fuzzy-features": [RANGE_SEPARATION_M - shrunk, RANGE_SEPARATION_M + shrunk],
    }


def regions_table(p_gate: float = 0.99) -> pd.DataFrame:
    """One row per boundary: ``band, label, index, left, right, x_m`` and the closed form with its error."""
    closed = closed_form_boundaries(p_gate)
    frames = []
    for band, (label, *_rest) in BANDS.items():
        found = find_boundaries(band, p_gate)
        found.insert(0, "index", np.arange(len(found)))
        found.insert(0, "label", label)
        found.insert(0, "band", band)
        expected = closed[band] if len(closed[band]) == len(found) else [math.nan] * len(found)
        found["closed_form_m"] = expected
        found["error_m"] = found["x_m"] - found["closed_form_m"]
        frames.append(found)
    table = pd.concat(frames, ignore_index=True)
    table.insert(1, "p_gate", p_gate)
    return table


def band_segments(table: pd.DataFrame, band: str, x_range=X_RANGE_M) -> list[tuple[float, float, str]]:
    """``(x_from, x_to, choice)`` of a band over ``x_range`` from its boundary rows."""
    rows = table[table["band"] == band].sort_values("x_m")
    edges = [x_range[0], *rows["x_m"].tolist(), x_range[1]]
    if len(rows):
        names = [rows["left"].iloc[0], *rows["right"].tolist()]
    else:
        middle = 0.5 * (x_range[0] + x_range[1])
        names = [CHOICE_NAMES[int(choices_along_line(band, np.array([middle]))[0])]]
    return [(edges[i], edges[i + 1], names[i]) for i in range(len(names))]


def plot_regions(table: pd.DataFrame, x_range=X_RANGE_M):
    """Three horizontal bands coloured by the chosen hypothesis, the boundaries annotated; returns the figure."""
    plt = pyplot()
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(10.0, 4.0))
    bands = list(BANDS)
    height = 0.5
    for row, band in enumerate(bands):
        y = len(bands) - 1 - row  # first band on top
        for x_from, x_to, name in band_segments(table, band, x_range):
            ax.barh(y, x_to - x_from, left=x_from, height=height, color=CHOICE_COLOURS[name], edgecolor="white")
        rows = table[table["band"] == band]
        for k, x_m in enumerate(rows["x_m"]):
            ax.plot([x_m, x_m], [y - height / 2, y + height / 2], color="black", linewidth=0.8)
            above = k % 2 == 0  # neighbouring boundaries alternate above / below the band
            ax.text(x_m, y + (height / 2 + 0.04) * (1 if above else -1), f"{x_m:.3f}", ha="center",
                    va="bottom" if above else "top", fontsize="x-small")
    ax.set_yticks(range(len(bands)), [BANDS[band][0] for band in reversed(bands)])
    ax.set_ylim(-0.6, len(bands) - 0.4)
    ax.set_xlim(*x_range)
    ax.set_xlabel("plot range offset x from track A's predicted range [m] (track B at x = 300 m)")
    ax.set_ylabel("rule")
    ax.set_title("E2: chosen hypothesis along the TV9 line\n"
                 f"(S_B = 9 S_A, P_G = {table['p_gate'].iloc[0]:g}; the features band has a foe / 5670 plot)")
    ax.legend(handles=[Patch(color=CHOICE_COLOURS[n], label=CHOICE_LABELS[n]) for n in ("A", "B", "new")],
              loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize="small", frameon=False)
    fig.tight_layout()
    return fig


def run_regions(out_dir: Path, p_gate: float = 0.99) -> pd.DataFrame:
    """E2: boundaries of the three bands; writes the CSV and the PNG to ``out_dir``; returns the table."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    table = regions_table(p_gate)
    table.to_csv(out_dir / CSV_NAME, index=False, float_format="%.10g")
    save_figure(plot_regions(table), out_dir / PNG_NAME)
    return table


def check_regions(table: pd.DataFrame) -> list[Check]:
    """TV9: the sequence of choices and every boundary within 1e-3 m (P_G = 0.99)."""
    checks = []
    for band, expected in TV9_BOUNDARIES.items():
        rows = table[table["band"] == band]
        got_order = list(zip(rows["left"], rows["right"]))
        want_order = [(a, b) for a, b, _ in expected]
        checks.append(Check(f"{band}: choices along x", " ".join([a for a, _ in got_order] + [got_order[-1][1]]) if got_order else "–",
                            " ".join([a for a, _ in want_order] + [want_order[-1][1]]), got_order == want_order))
        if got_order != want_order:
            continue
        for (left, right, want), x_m in zip(expected, rows["x_m"]):
            checks.append(Check(f"{band}: {left} | {right}", f"{x_m:.4f} m", f"{want:.3f} ± {TV9_TOLERANCE_M:g} m",
                                abs(x_m - want) <= TV9_TOLERANCE_M))
    return checks

"""Figure of study E4 (spec 003 §6): swap rate and CAR against the IFF error rate (S2), one line per
method, and the swap rate per interrogation policy as bars (S1).

:func:`crossing_figure` returns the matplotlib figure so that tests can read what is drawn
(line labels, bar heights, error bars).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.studies.fuzzy.crossing import METHODS

#: one colour and marker per method (colour-blind-safe Okabe-Ito palette)
STYLE = {"nn": ("#000000", "o"), "ml": ("#E69F00", "s"), "fuzzy": ("#0072B2", "^"),
         "fuzzy-global": ("#009E73", "D"), "crisp": ("#CC79A7", "v")}


def crossing_figure(table: pd.DataFrame, path: Path | None = None):
    """Three panels: swap rate and CAR vs error rate (policy ``always``, p_flip = p_code), swap
    rate per policy (errors 0).  Rows missing from ``table`` are left out of their panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_swap, ax_car, ax_policy) = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    runs = int(table["runs"].max())
    errors = table[(table.policy == "always") & np.isclose(table.p_flip, table.p_code) & (table.beta_deg == 5.0)
                   & (table.q == 25.0) & (table.missing_iff == "undetermined")]
    for method in METHODS:
        rows = errors[errors.method == method].drop_duplicates("p_flip").sort_values("p_flip")
        if rows.empty:
            continue
        colour, marker = STYLE[method]
        ax_swap.errorbar(rows.p_flip, rows.swap, yerr=rows.swap_se, color=colour, marker=marker, capsize=3,
                         label=method)
        ax_car.errorbar(rows.p_flip, rows.car, yerr=rows.car_se_runs, color=colour, marker=marker, capsize=3,
                        label=method)
    ax_swap.set(xlabel="IFF error rate p_flip = p_code", ylabel="identity-swap rate", ylim=(-0.02, None),
                title="Swaps vs IFF errors (policy: always)")
    ax_car.set(xlabel="IFF error rate p_flip = p_code", ylabel="correct-association rate (CAR)",
               title="CAR vs IFF errors (policy: always)")
    base = table[(table.p_flip == 0) & (table.p_code == 0) & (table.beta_deg == 5.0) & (table.q == 25.0)
                 & (table.missing_iff == "undetermined")]
    policies = [p for p in ("track", "always") if p in set(base.policy)]
    width = 0.8 / len(METHODS)
    for i, method in enumerate(METHODS):
        rows = base[base.method == method].drop_duplicates("policy").set_index("policy").reindex(policies)
        colour, _ = STYLE[method]
        ax_policy.bar(np.arange(len(policies)) + (i - (len(METHODS) - 1) / 2) * width, rows.swap, width,
                      yerr=rows.swap_se, color=colour, capsize=2, label=method)
    ax_policy.set_xticks(np.arange(len(policies)), [f"policy: {p}" for p in policies])
    ax_policy.set(ylabel="identity-swap rate", title="Swaps per interrogation policy (IFF errors 0)")
    for ax in (ax_swap, ax_car, ax_policy):
        ax.grid(alpha=0.3)
        ax.legend(title="method", fontsize=8)
    fig.suptitle(f"spec 003 E4: crossing targets, beta = 5 deg, q = 25 m^2/s^3, {runs} runs per configuration "
                 "(error bars: 1 SE)")
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig

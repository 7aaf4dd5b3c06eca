"""Many-to-many assignment of identified pairs: spec 001 R13 step 4 and step 6 (TV-6).

The pairs allowed are those with dof ≥ dof_min and Λ ≤ h (Neyman–Pearson mode, cost
Λ − h with h from R5 for the pair's dof) or ln BF > 0 (Bayesian mode, cost −ln BF, R6).
The global solver is a one-to-one assignment with a "no match" option of cost 0 — the
(N+M)×(M+N) augmented problem of R13, solved on the sparse pair graph by
:func:`skytrack.association.gnn.assign_gnn` (one ``linear_sum_assignment`` per connected
component, lone pairs directly).  ``solver="greedy"`` takes pairs by ascending Λ, for
comparison (E9).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.association.gnn import assign_gnn

SOLVERS = ("global", "greedy")


@dataclass(frozen=True)
class PairTable:
    """Candidate pairs (rows of two track sets) with their statistic, threshold and cost."""

    first: np.ndarray
    """row of the system-1 track"""
    second: np.ndarray
    """row of the system-2 track"""
    statistic: np.ndarray
    dof: np.ndarray
    threshold: np.ndarray
    allowed: np.ndarray
    cost: np.ndarray


def assign_pairs(table: PairTable, n_first: int, n_second: int, solver: str = "global") -> np.ndarray:
    """Indices (into ``table``) of the chosen pairs: one-to-one, only allowed pairs, minimal total cost."""
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
    candidates = np.flatnonzero(table.allowed)
    if len(candidates) == 0:
        return candidates
    if solver == "global":
        chosen = assign_gnn(table.first[candidates], table.second[candidates], table.cost[candidates],
                            n_first, n_second, 0.0)
        return np.sort(candidates[chosen])
    return greedy_pairs(table.first[candidates], table.second[candidates], table.statistic[candidates],
                        candidates)


def greedy_pairs(first: np.ndarray, second: np.ndarray, statistic: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Ascending Λ, each track taken once (the comparison solver of R13)."""
    order = np.argsort(statistic, kind="stable")
    used_first, used_second, chosen = set(), set(), []
    # a sequential choice by construction; E9 and TV-6 only, never on a hot path
    for i in order:
        if first[i] in used_first or second[i] in used_second:
            continue
        used_first.add(first[i])
        used_second.add(second[i])
        chosen.append(index[i])
    return np.sort(np.asarray(chosen, dtype=np.intp))

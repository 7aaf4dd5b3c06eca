"""Association as parts: candidate search (gate), scorer and assigner.

A window's association is ``pairs = gate.candidates(...)`` -> the filter's innovation of
each pair -> ``scores = scorer.score(innovation, pairs)`` -> ``chosen = assigner.assign(scores,
n_tracks, n_plots)``.  Each part is registered by name (:mod:`skytrack.association.registry`),
so a fuzzy or maximum-likelihood scorer, or a greedy or sequential assigner, is one module
plus a registry entry.

* :class:`Pairs` — candidate (track row, plot row) pairs of one window.
* :class:`PairScores` — per-pair cost (lower is better), whether the pair is inside the
  gate, the cost of leaving each track unassigned (``miss_cost``), the cost of a plot
  starting a new object (``new_object_cost``, None when plots left over cost nothing) and
  per-pair diagnostic columns (``columns``) a scorer wants to report.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


@dataclass
class Pairs:
    track: np.ndarray
    plot: np.ndarray

    def __len__(self) -> int:
        return len(self.track)

    def take(self, rows) -> "Pairs":
        return Pairs(self.track[rows], self.plot[rows])


@dataclass
class PairScores:
    pairs: Pairs
    cost: np.ndarray
    inside: np.ndarray
    miss_cost: np.ndarray
    new_object_cost: np.ndarray | None = None
    columns: dict[str, np.ndarray] = field(default_factory=dict)

    def take(self, rows) -> "PairScores":
        return PairScores(self.pairs.take(rows), self.cost[rows], self.inside[rows], self.miss_cost,
                          None if self.new_object_cost is None else self.new_object_cost,
                          {k: v[rows] for k, v in self.columns.items()})


class Scorer(Protocol):
    """Turns the innovations of candidate pairs into costs, a gate decision and miss costs."""

    name: str

    def score(self, innovation, pairs: Pairs, n_tracks: int) -> PairScores: ...


class Assigner(Protocol):
    """Chooses at most one plot per track and one track per plot; returns indices of chosen pairs."""

    name: str

    def assign(self, scores: PairScores, n_tracks: int, n_plots: int) -> np.ndarray: ...

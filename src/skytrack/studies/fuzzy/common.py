"""Shared pieces of the spec 003 §6 studies (R20): expected-value checks and figure output.

* :class:`Check` — one expected value of the spec (E1-E3 "Expected" lines, TV9, TV11) against
  what a study measured; ``skytrack study fuzzy-* --check`` exits 1 when one fails;
* :func:`pyplot` — matplotlib with the non-interactive Agg backend (imported on use);
* :func:`save_figure` — a PNG of modest size, the figure closed afterwards;
* :data:`Progress` — the Monte Carlo progress callback ``progress(completed, total)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import pandas as pd

#: progress(completed, total), called after each Monte Carlo chunk
Progress = Optional[Callable[[int, int], None]]
FIGURE_DPI = 100


@dataclass(frozen=True)
class Check:
    """One expected value: ``name``, what was ``measured`` and ``expected`` (as text), ``passed``."""

    name: str
    measured: str
    expected: str
    passed: bool

    def __post_init__(self) -> None:
        object.__setattr__(self, "passed", bool(self.passed))  # numpy booleans print as np.True_


def checks_frame(checks: list[Check]) -> pd.DataFrame:
    return pd.DataFrame([c.__dict__ for c in checks], columns=["name", "measured", "expected", "passed"])


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path) -> Path:
    """Write ``fig`` as PNG and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=FIGURE_DPI)
    pyplot().close(fig)
    return path

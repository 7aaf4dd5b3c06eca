"""Shared pieces of the spec 001 §6 identification studies (E1-E4).

* :class:`Check` (from the spec 003 studies) — one expected value against what a study measured;
* :func:`binomial_se` and :func:`within_se` — the Monte Carlo tolerance of an estimated probability;
* :func:`chunk_sizes` — the Monte Carlo draws split into chunks (one progress step each);
* :func:`write_summary` — the JSON summary ``{"study", "options", "results", "checks", "passed"}``;
* :func:`pyplot`, :func:`save_figure` — matplotlib (Agg) and PNG output, as in the other studies.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from skytrack.studies.fuzzy.common import Check, Progress, pyplot, save_figure
from skytrack.studies.maneuver.outputs import jsonable

__all__ = ["Check", "Progress", "pyplot", "save_figure", "binomial_se", "within_se", "chunk_sizes",
           "write_summary", "jsonable", "MC_SIGMAS", "CHUNK_DRAWS"]

#: a Monte Carlo estimate passes when within this many standard errors of the exact value
MC_SIGMAS = 4.0
#: draws per chunk (one progress step, bounded memory)
CHUNK_DRAWS = 200_000


def binomial_se(p, n: int):
    """Standard error of a frequency over n draws of a probability p (floored at one draw's worth)."""
    p = np.asarray(p, dtype=float)
    return np.sqrt(np.maximum(p * (1.0 - p), 1.0 / n) / n)


def within_se(measured, exact, n: int, sigmas: float = MC_SIGMAS) -> bool:
    """True when every ``|measured - exact| <= sigmas * binomial_se(exact, n)``."""
    return bool(np.all(np.abs(np.asarray(measured) - np.asarray(exact)) <= sigmas * binomial_se(exact, n)))


def chunk_sizes(trials: int, chunk: int = CHUNK_DRAWS) -> list[int]:
    """``trials`` split into chunks of at most ``chunk`` draws."""
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    return [min(chunk, trials - start) for start in range(0, trials, chunk)]


def write_summary(path: Path, study: str, options: dict, results: dict, checks: list[Check]) -> Path:
    """Write the study's JSON summary and return its path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    document = {"study": study, "options": options, "results": results,
                "checks": [c.__dict__ for c in checks], "passed": all(c.passed for c in checks)}
    path.write_text(json.dumps(jsonable(document), indent=2, ensure_ascii=False) + "\n")
    return path

"""Shared pieces of the Monte Carlo identification studies E5-E9 of spec 001 §6 (R16).

* :class:`StudyOutput` — what a study returns to the CLI: its main table, the checks of the
  spec's expected values, the files written and the JSON results;
* :func:`tolerance_scale` — a tolerance the spec states for N₀ runs, used with N runs, is
  multiplied by √(N₀/N) (the Monte Carlo error scales so);
* :func:`within` / :func:`within_se` checks; :func:`chunked` splits trials for the progress bar;
* :func:`finish` writes the CSV, the PNG and the JSON summary (``{"study", "options",
  "results", "checks", "passed"}`` via :func:`~skytrack.studies.identification.common.write_summary`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.studies.identification.common import Check, Progress, save_figure, write_summary

__all__ = ["Check", "Progress", "StudyOutput", "tolerance_scale", "within", "within_se", "chunked", "finish",
           "SE_SIGMAS", "frequency_se"]

#: a Monte Carlo frequency passes when within this many standard errors of its exact value
SE_SIGMAS = 4.0


@dataclass
class StudyOutput:
    """A study's main table, its checks, the files it wrote and its JSON results."""

    table: pd.DataFrame
    checks: list[Check]
    paths: list[Path]
    results: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)


def tolerance_scale(trials: int, reference_trials: int) -> float:
    """√(reference/trials): the factor on a tolerance the spec states for ``reference_trials`` runs."""
    return float(np.sqrt(reference_trials / trials))


def frequency_se(p, n: int):
    """Binomial standard error of a frequency of probability ``p`` over ``n`` draws (≥ one draw's worth)."""
    p = np.asarray(p, float)
    return np.sqrt(np.maximum(p * (1.0 - p), 1.0 / n) / n)


def within(name: str, measured: float, expected: float, tolerance: float, digits: int = 6,
           relative: bool = False) -> Check:
    """``|measured − expected| ≤ tolerance`` (× |expected| when ``relative``)."""
    bound = tolerance * abs(expected) if relative else tolerance
    spec = f"{expected:.{digits}g} ± {tolerance:.2g}{' rel.' if relative else ''}"
    return Check(name, f"{measured:.{digits}g}", spec, bool(abs(measured - expected) <= bound))


def within_se(name: str, measured: float, exact: float, n: int, sigmas: float = SE_SIGMAS) -> Check:
    """A Monte Carlo frequency against its exact probability, within ``sigmas`` binomial SE."""
    se = float(frequency_se(exact, n))
    z = (measured - exact) / se
    return Check(name, f"{measured:.6g} (z = {z:+.2f})", f"{exact:.6g} ± {sigmas:g} SE ({se:.2g})",
                 bool(abs(z) <= sigmas))


def chunked(trials: int, chunk: int) -> list[int]:
    """``trials`` in chunks of at most ``chunk`` (one progress step each)."""
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials}")
    return [min(chunk, trials - start) for start in range(0, trials, chunk)]


def finish(out_dir: Path, name: str, table: pd.DataFrame, figure, options: dict, results: dict,
           checks: list[Check], extra_tables: dict[str, pd.DataFrame] | None = None) -> list[Path]:
    """Write ``<name>.csv`` (and ``<name>_<key>.csv`` for ``extra_tables``), ``<name>.png`` and
    ``<name>_summary.json``; returns the paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}.csv"]
    table.to_csv(paths[0], index=False, float_format="%.10g")
    for key, extra in (extra_tables or {}).items():
        paths.append(out_dir / f"{name}_{key}.csv")
        extra.to_csv(paths[-1], index=False, float_format="%.10g")
    paths.append(save_figure(figure, out_dir / f"{name}.png"))
    paths.append(write_summary(out_dir / f"{name}_summary.json", name.replace("_", "-"), options, results, checks))
    return paths

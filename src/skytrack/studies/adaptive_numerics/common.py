"""Outputs shared by the spec 002 §6 studies E5-E7: expected-value checks, CSV, PNG and the JSON summary.

Each study writes ``<name>.csv`` (its table), ``<name>.png`` (its figure), ``<name>.json`` (options,
the checked expectations with measured values and verdicts, and what the figure draws).  Checks reuse
:class:`skytrack.studies.fuzzy.common.Check`; a study's ``--check`` exits 1 when one fails.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from skytrack.studies.fuzzy.common import Check, checks_frame, pyplot, save_figure
from skytrack.studies.maneuver.outputs import jsonable

__all__ = ["Check", "checks_frame", "pyplot", "save_figure", "describe_figure", "write_outputs", "within_factor"]


def within_factor(measured: float, expected: float, factor: float) -> bool:
    """Order-of-magnitude agreement: ``expected / factor <= measured <= expected * factor`` (same sign)."""
    if expected == 0 or measured == 0 or (measured > 0) != (expected > 0):
        return False
    ratio = measured / expected
    return 1.0 / factor <= ratio <= factor


def describe_figure(fig) -> list[dict]:
    """Title, axis labels and scales, and the labelled lines of every axes (for the JSON summary)."""
    axes = []
    for ax in fig.axes:
        axes.append({"title": ax.get_title(), "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
                     "xscale": ax.get_xscale(), "yscale": ax.get_yscale(),
                     "lines": [line.get_label() for line in ax.get_lines() if not line.get_label().startswith("_")]})
    return axes


def write_outputs(out_dir: Path, name: str, table: pd.DataFrame, fig, checks: list[Check], options: dict,
                  extra_tables: dict[str, pd.DataFrame] | None = None, results: dict | None = None) -> list[Path]:
    """Write ``name.csv``, the extra CSVs, ``name.png`` and ``name.json``; returns the paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{name}.csv"]
    table.to_csv(paths[0], index=False, float_format="%.12g")
    for suffix, extra in (extra_tables or {}).items():
        path = out_dir / f"{name}_{suffix}.csv"
        extra.to_csv(path, index=False, float_format="%.9g")
        paths.append(path)
    summary = {"study": name, "options": options, "results": results or {},
               "checks": checks_frame(checks).to_dict(orient="records"),
               "passed": all(c.passed for c in checks), "figure": describe_figure(fig)}
    png = save_figure(fig, out_dir / f"{name}.png")
    json_path = out_dir / f"{name}.json"
    json_path.write_text(json.dumps(jsonable(summary), indent=2, ensure_ascii=False))
    return [*paths, png, json_path]

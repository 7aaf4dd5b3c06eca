"""Study outputs (spec 004 R23): summary.csv, timeseries.parquet, PNG figures, claims.json.

* ``summary.csv`` — one row per (case, filter, gating, basis, onset) with the R20 metrics of
  :mod:`skytrack.studies.maneuver.metrics` (plus any study rows);
* ``timeseries.parquet`` — tidy rows ``series, case, filter, basis, onset, t, t_rel, quantity,
  value`` (pivot on ``quantity`` for wide tables); a study adds its own series (gains, mode
  probabilities, R-hat histories) under its own ``series`` name;
* ``timing.csv`` — wall microseconds per update (R22 b) per filter and case: the one output
  that differs between two runs with the same seed, so it is kept apart;
* figures — PNG, every axes with labelled x and y, a legend when it draws more than one
  labelled line, distinct colours (:func:`colours`); ``figures.json`` describes what each
  figure draws (title, axis labels, line labels, read from the matplotlib axes before saving);
* ``claims.json`` — ``{"study", "options", "claims": [{"id", "kind", "description", "criterion",
  "measured", "verdict", "paper"}], "asserts_passed"}``; ``kind`` is ``assert`` (verdict true or
  false; a measurement that is not finite fails) or ``report`` (verdict null).  ``--check``
  exits non-zero when an assert failed.

JSON has no infinities: non-finite numbers are written as the strings ``"inf"``, ``"-inf"``
and ``null`` for NaN.
"""

from __future__ import annotations

import contextlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

SUMMARY_NAME = "summary.csv"
TIMESERIES_NAME = "timeseries.parquet"
TIMING_NAME = "timing.csv"
CLAIMS_NAME = "claims.json"
FIGURES_NAME = "figures.json"
TIMESERIES_COLUMNS = ("series", "case", "filter", "basis", "onset", "t", "t_rel", "quantity", "value")
CLAIM_KINDS = ("assert", "report")


def jsonable(value):
    """Plain JSON values: numpy scalars and arrays to Python, NaN to None, +-inf to strings."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if math.isnan(value):
            return None
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return value
    if isinstance(value, Path):
        return str(value)
    return value


@dataclass
class Claim:
    """One claim of a study: ``assert`` (checked, verdict) or ``report`` (number only)."""

    id: str
    kind: str
    description: str
    measured: dict
    criterion: str = ""
    verdict: bool | None = None
    paper: str = ""

    def __post_init__(self) -> None:
        if self.kind not in CLAIM_KINDS:
            raise ValueError(f"claim {self.id!r}: kind must be one of {CLAIM_KINDS}, got {self.kind!r}")
        if self.kind == "assert" and self.verdict is None:
            raise ValueError(f"claim {self.id!r}: an assert needs a verdict")
        if self.kind == "report" and self.verdict is not None:
            raise ValueError(f"claim {self.id!r}: a report has no verdict")

    def to_json(self) -> dict:
        return jsonable({"id": self.id, "kind": self.kind, "description": self.description, "criterion": self.criterion,
                         "measured": self.measured, "verdict": self.verdict, "paper": self.paper})


def finite_verdict(passed, *values) -> bool:
    """``passed`` as a bool, False when any of ``values`` is not finite (an unmeasured assert fails)."""
    for value in values:
        array = np.asarray(value, dtype=float)
        if array.size == 0 or not np.all(np.isfinite(array)):
            return False
    return bool(passed)


def colours(count: int) -> list:
    """``count`` distinct colours (tab10 up to 10, then tab20, then evenly spaced hues)."""
    import matplotlib

    if count <= 10:
        return [matplotlib.colormaps["tab10"](i) for i in range(count)]
    if count <= 20:
        return [matplotlib.colormaps["tab20"](i) for i in range(count)]
    return [matplotlib.colormaps["hsv"](i / count) for i in range(count)]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def describe_axes(ax) -> dict:
    """What an axes draws: title, axis labels, labelled lines and legend entries."""
    lines = [line for line in ax.get_lines() if not str(line.get_label()).startswith("_")]
    legend = ax.get_legend()
    return {
        "title": ax.get_title(),
        "xlabel": ax.get_xlabel(),
        "ylabel": ax.get_ylabel(),
        "lines": len(ax.get_lines()),
        "labels": [str(line.get_label()) for line in lines],
        "colours": [list(map(float, _rgba(line.get_color()))) for line in lines],
        "legend": [t.get_text() for t in legend.get_texts()] if legend is not None else [],
        "collections": len(ax.collections),
    }


def _rgba(colour):
    from matplotlib.colors import to_rgba

    return to_rgba(colour)


@dataclass
class FigureLog:
    """Descriptions of the figures written by a study (``figures.json``)."""

    entries: list = field(default_factory=list)

    @contextlib.contextmanager
    def figure(self, path: Path, title: str, nrows: int = 1, ncols: int = 1, figsize=None, sharex: bool = False):
        """Yield ``(fig, axes_list)``; on exit check the labelling rules, describe, save as PNG and close."""
        plt = _pyplot()
        figsize = figsize or (6.4 * ncols, 4.4 * nrows)
        fig, axes = plt.subplots(nrows, ncols, figsize=figsize, squeeze=False, sharex=sharex)
        flat = list(axes.ravel())
        try:
            yield fig, flat
            described = []
            for ax in flat:
                if not ax.has_data():
                    ax.set_visible(False)
                    continue
                if not ax.get_xlabel() or not ax.get_ylabel():
                    raise ValueError(f"figure {Path(path).name}: every axes needs x and y labels")
                labelled = [line for line in ax.get_lines() if not str(line.get_label()).startswith("_")]
                if len(labelled) > 1 and ax.get_legend() is None:
                    ax.legend(fontsize="small")
                ax.grid(True, alpha=0.3)
                described.append(describe_axes(ax))
            fig.suptitle(title)
            fig.tight_layout()
            fig.savefig(path, dpi=110)
            self.entries.append({"file": Path(path).name, "title": title, "axes": described})
        finally:
            plt.close(fig)


def write_summary(rows: list[dict], path: Path) -> Path:
    frame = pd.DataFrame(rows)
    frame.to_csv(path, index=False, float_format="%.10g")
    return path


def write_timeseries(frames: list[pd.DataFrame], path: Path) -> Path:
    if frames:
        table = pd.concat(frames, ignore_index=True)
    else:
        table = pd.DataFrame({name: [] for name in TIMESERIES_COLUMNS})
    for name in ("series", "case", "filter", "basis", "quantity"):
        if name in table.columns:
            table[name] = table[name].astype(str)
    table.to_parquet(path, index=False)
    return path


def write_claims(study: str, options: dict, claims: list[Claim], path: Path) -> Path:
    ids = [c.id for c in claims]
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise ValueError(f"study {study}: claim ids repeated: {repeated}")
    payload = {
        "study": study,
        "options": jsonable(options),
        "claims": [c.to_json() for c in claims],
        "asserts_passed": all(c.verdict for c in claims if c.kind == "assert"),
    }
    path.write_text(json.dumps(payload, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def write_figure_log(log: FigureLog, path: Path) -> Path:
    path.write_text(json.dumps(jsonable(log.entries), indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return path


def plot_aligned_rms(log: FigureLog, path: Path, series: pd.DataFrame, title: str, *, basis: str = "all",
                     onset: int = 0, filters: list[str] | None = None) -> None:
    """RMS position (left) and velocity (right) error vs time from onset from the tidy ``aligned``
    time series: one colour per filter and one line style per case (one colour per case when
    only one filter is drawn)."""
    rows = series[(series["series"] == "aligned") & (series["basis"] == basis) & (series["onset"] == onset)]
    filters = filters or list(dict.fromkeys(rows["filter"]))
    cases = list(dict.fromkeys(rows["case"]))
    styles = ["-", "--", ":", "-."]
    by_case = len(filters) == 1  # one filter: the cases get the colours
    palette = colours(len(cases) if by_case else len(filters))
    with log.figure(path, title, 1, 2) as (_, axes):
        for ax, quantity, unit in zip(axes, ("rms_pos", "rms_vel"), ("m", "m/s")):
            for i, name in enumerate(filters):
                for j, case in enumerate(cases):
                    part = rows[(rows["filter"] == name) & (rows["case"] == case) & (rows["quantity"] == quantity)]
                    if part.empty:
                        continue
                    label = name if len(cases) == 1 else f"{name}, {case}"
                    style, colour = ("-", palette[j]) if by_case else (styles[j % len(styles)], palette[i])
                    ax.plot(part["t_rel"], part["value"], style, color=colour, label=label)
            ax.set_xlabel("time from manoeuvre onset [s]")
            ax.set_ylabel(f"RMS {'position' if quantity == 'rms_pos' else 'velocity'} error [{unit}]")
            ax.set_yscale("log")

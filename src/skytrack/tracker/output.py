"""Track output: output instants and the rows of the tracks table (docs/formats.md).

Confirmed tracks are reported at output instants — the end of every scan of the first
radar, or every ``output_interval_s`` — predicted to the instant, while they probably still
exist (fewer than ``report_max_misses`` consecutive misses: :func:`reported_rows`).  Each instant keeps a compact record
(:func:`instant_record`); one table is built per :meth:`~skytrack.tracker.tracker.Tracker.drain`
(:func:`build_table`), with one geodetic conversion and one identity decoding for all its rows;
:func:`tracks_frame` makes it a DataFrame, :func:`tracks_arrow` an Arrow table for a writer
(no DataFrame on the way to the file).
2-D tracks carry ``z`` null and their last Mode C altitude as ``alt_m``; lat/lon come from
the ENU position (at the last plot's height for 2-D tracks).  ``identity_source`` and
``identity_p`` come from the tracks' reply counts (:func:`skytrack.tracker.identity.identity_probability`,
with the per-reply error probability ``identity_error_p``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from skytrack.core.plots import icao24_text, iff_text, mode3a_text
from skytrack.core.tracks import EMPTY_COLUMNS, covariance_columns
from skytrack.geo.wgs84 import enu_to_geodetic_closed_form
from skytrack.tracker.bank import CONFIRMED, TrackBank
from skytrack.tracker.identity import DEFAULT_ERROR_P, identity_probability, source_text


@dataclass
class OutputConfig:
    """``report_max_misses``: a confirmed track is reported only while it has fewer consecutive
    misses than this (it probably still exists; 0 reports every confirmed track until deleted).
    ``identity_error_p``: the probability that one reply (IFF status, Mode 3/A code, Mode S
    address) is wrong, behind ``identity_p`` (:mod:`skytrack.tracker.identity`)."""

    output_interval_s: float | None = None
    full_covariance: bool = False
    report_max_misses: int = 4
    identity_error_p: float = DEFAULT_ERROR_P

    def __post_init__(self) -> None:
        if self.output_interval_s is not None and not self.output_interval_s > 0:
            raise ValueError(f"output_interval_s must be > 0, got {self.output_interval_s}")
        if self.report_max_misses < 0:
            raise ValueError(f"report_max_misses must be >= 0, got {self.report_max_misses}")
        if not 0.0 < self.identity_error_p < 0.5:
            raise ValueError(f"identity_error_p must be in (0, 0.5), got {self.identity_error_p}")


def reported_rows(bank: TrackBank, max_misses: int) -> np.ndarray:
    """The bank rows reported at an output instant: confirmed tracks with fewer than
    ``max_misses`` consecutive misses (every confirmed track when it is 0)."""
    reported = bank.status == CONFIRMED
    if max_misses > 0:
        reported &= bank.n_misses < max_misses
    return np.flatnonzero(reported)


class OutputClock:
    """When to report: every output interval, else every scan of the first radar, else every window."""

    def __init__(self, config: OutputConfig, rotating: bool, period: float, window_s: float) -> None:
        self.config = config
        self.rotating = rotating
        self.period = period
        self.window_s = window_s
        self.next: float | None = None

    def start(self, first_time: float, phase: float) -> None:
        step = self.config.output_interval_s
        if step is not None:
            self.next = math.floor(first_time / step) * step + step
        elif self.rotating and not np.isnan(phase):
            self.next = phase + (math.floor((first_time - phase) / self.period) + 1) * self.period
        else:
            self.next = first_time + self.window_s

    @property
    def step(self) -> float:
        if self.config.output_interval_s is not None:
            return self.config.output_interval_s
        return float(self.period) if self.rotating else self.window_s

    def skip_to(self, limit: float) -> None:
        """Advance past the instants not after ``limit`` without reporting them."""
        if self.next is not None and self.next <= limit + 1e-9:
            self.next += (math.floor((limit + 1e-9 - self.next) / self.step) + 1) * self.step

    def instants_until(self, limit: float):
        """Output instants not after ``limit`` (advances the clock)."""
        if self.next is None:
            return
        while self.next <= limit + 1e-9:
            yield self.next
            self.next += self.step


def instant_record(instant: float, rows: np.ndarray, x: np.ndarray, P: np.ndarray, bank: TrackBank,
                   full_covariance: bool, model_probs: np.ndarray | None = None,
                   identity_error_p: float = DEFAULT_ERROR_P) -> dict[str, np.ndarray]:
    """What one output instant contributes: the bank's rows ``rows`` with states ``x``, ``P`` at
    ``instant``, kept compact (variances, or the covariance's upper triangle) until
    :func:`build_table` makes the table's columns for a whole drain at once.  ``model_probs``
    ``[K, M]``: a multiple-model filter's model probabilities; ``identity_error_p`` the per-reply
    error probability behind ``identity_p``."""
    n = x.shape[1]
    source, identity_p = identity_probability(bank.identity, bank.mode3a, bank.icao24, bank.iff, identity_error_p,
                                              rows)
    record = {
        "time": np.full(len(rows), instant), "track_id": bank.track_id[rows], "x": x,
        "var": np.diagonal(P, axis1=1, axis2=2), "n_updates": bank.n_updates[rows],
        "n_misses": bank.n_misses[rows], "alt_m": bank.alt_m[rows], "z_hint": bank.z_hint[rows],
        "mode3a": bank.mode3a[rows], "icao24": bank.icao24[rows], "iff": bank.iff[rows],
        "identity_source": source, "identity_p": identity_p,
    }
    if full_covariance:
        iu, ju = np.triu_indices(n)
        record["upper"] = P[:, iu, ju]
    if model_probs is not None:
        record["model_probs"] = model_probs
    return record


#: pyarrow's string arrays have 32-bit offsets: longer text is split into chunks
MAX_STRING_CHUNK_BYTES = 2**31 - 1


def model_probs_text(probabilities: np.ndarray, names: tuple[str, ...]):
    """The ``model_probs`` column: one JSON object per row, model name -> probability with 4
    decimals (``{"CV": 0.9123, "CT +3 deg/s": 0.0500}``).

    Every probability is written ``d.dddd``, so every row has the same length: the digits are
    placed into one byte buffer with numpy and the buffer becomes a pyarrow string array as it is
    (chunks below pyarrow's 2 GiB offset limit)."""
    import json

    import pyarrow as pa

    rows = len(probabilities)
    ticks = np.rint(np.clip(probabilities, 0.0, 1.0) * 1e4).astype(np.int64)
    template, value_at = "", []
    for j, name in enumerate(names):
        template += ("{" if j == 0 else ", ") + json.dumps(str(name)) + ": "
        value_at.append(len(template))
        template += "0.0000"
    template += "}"
    width = len(template)
    text = np.tile(np.frombuffer(template.encode("ascii"), np.uint8), (rows, 1))
    zero = ord("0")
    for j, at in enumerate(value_at):
        text[:, at] = zero + ticks[:, j] // 10000
        for place, power in enumerate((1000, 100, 10, 1)):
            text[:, at + 2 + place] = zero + ticks[:, j] // power % 10
    per_chunk = max(1, MAX_STRING_CHUNK_BYTES // width)
    chunks = []
    for first in range(0, max(rows, 1), per_chunk):
        count = min(per_chunk, rows - first)
        offsets = np.arange(count + 1, dtype=np.int32) * width
        data = np.ascontiguousarray(text[first:first + count]).reshape(-1)
        chunks.append(pa.StringArray.from_buffers(count, pa.py_buffer(offsets), pa.py_buffer(data)))
    return chunks[0] if len(chunks) == 1 else pa.chunked_array(chunks, pa.string())


def _status_text(coasting: np.ndarray):
    import pyarrow as pa

    return pa.DictionaryArray.from_arrays(pa.array(coasting.astype(np.int8)), pa.array(["confirmed", "coasting"]))


def build_table(records: list[dict[str, np.ndarray]], dim: int, order: int, origin,
                model_names: tuple[str, ...] | None = None) -> dict[str, object]:
    """The tracks-table columns (docs/formats.md order) of concatenated instant records.

    Numbers are numpy arrays (NaN where unknown), text columns pyarrow arrays (null where
    unknown; dictionary-encoded when the tracker fills them); :func:`tracks_frame` or
    :func:`tracks_arrow` make the table.
    """
    import pyarrow as pa

    # matrices are joined transposed: each state component becomes one contiguous column
    matrices = ("x", "var", "upper")
    parts = {name: np.concatenate([r[name].T if name in matrices else r[name] for r in records],
                                  axis=1 if name in matrices else 0) for name in records[0]}
    x, var = parts["x"], parts["var"]
    count = x.shape[1]
    nan = np.full(count, np.nan)
    pos = np.arange(dim) * order
    vel = pos + 1
    columns: dict[str, object] = {"time": parts["time"], "track_id": parts["track_id"]}
    for axis, name in enumerate("xyz"):
        columns[name] = x[pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[name] = x[vel[axis]] if axis < dim else nan
    for axis, name in enumerate("xyz"):
        columns[f"var_{name}"] = var[pos[axis]] if axis < dim else nan
    for axis, name in enumerate(("vx", "vy", "vz")):
        columns[f"var_{name}"] = var[vel[axis]] if axis < dim else nan
    z = x[pos[2]] if dim == 3 else np.nan_to_num(parts["z_hint"])
    lat, lon, alt = enu_to_geodetic_closed_form(x[pos[0]], x[pos[1]], z, origin.lat, origin.lon, origin.alt_m)
    columns["lat"], columns["lon"] = lat, lon
    columns["alt_m"] = alt if dim == 3 else parts["alt_m"]
    columns["status"] = _status_text(parts["n_misses"] > 0)
    columns["n_updates"] = parts["n_updates"]
    columns["n_misses"] = parts["n_misses"]
    columns["mode3a"] = mode3a_text(parts["mode3a"])
    columns["icao24"] = icao24_text(parts["icao24"])
    columns["callsign"] = pa.nulls(count, pa.string())
    columns["iff"] = iff_text(parts["iff"])
    columns["identity_source"] = source_text(parts["identity_source"])
    columns["identity_p"] = parts["identity_p"]
    if "model_probs" in parts and model_names is not None:
        columns["model_probs"] = model_probs_text(parts["model_probs"], model_names)
    else:
        columns["model_probs"] = pa.nulls(count, pa.string())
    if "upper" in parts:
        upper = parts["upper"]
        for k, name in enumerate(covariance_columns(x.shape[0])):
            columns[name] = upper[k]
    return columns


def tracks_frame(columns: dict[str, object]) -> pd.DataFrame:
    """The tracks DataFrame of :func:`build_table`'s columns: text as pandas "str", the columns
    the tracker leaves empty as object columns of None (as :func:`~skytrack.core.tracks.empty_tracks`)."""
    import pyarrow as pa

    frame = {}
    for name, values in columns.items():
        if name in EMPTY_COLUMNS and values.null_count == len(values):
            frame[name] = np.full(len(values), None, dtype=object)
        elif isinstance(values, pa.Array):
            plain = values.dictionary_decode() if isinstance(values, pa.DictionaryArray) else values
            frame[name] = pd.array(plain, dtype="str")
        else:
            frame[name] = values
    return pd.DataFrame(frame)


def tracks_arrow(columns: dict[str, object]):
    """The tracks of :func:`build_table`'s columns as a pyarrow Table, typed as the tracks file
    stores them: float64 with NaN written as null (as a DataFrame's NaN is), int64, text
    (dictionary-encoded where the tracker fills it)."""
    import pyarrow as pa

    arrays = []
    for values in columns.values():
        if isinstance(values, pa.Array):
            arrays.append(values)
        elif values.dtype.kind == "f":
            # NaN becomes null; a mask only where there is a NaN (pyarrow's from_pandas scan
            # costs 20 times more than numpy's)
            missing = np.isnan(values)
            values = np.ascontiguousarray(values, dtype=np.float64)
            arrays.append(pa.array(values, mask=missing) if missing.any() else pa.array(values))
        else:
            arrays.append(pa.array(values, type=pa.int64()))
    return pa.Table.from_arrays(arrays, names=list(columns))

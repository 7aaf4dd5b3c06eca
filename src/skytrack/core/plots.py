"""PlotBatch: radar plots as typed arrays in SI units, identity as integer codes.

Plots are parsed once: the io readers (or :meth:`PlotBatch.from_frame` for a table in
memory, e.g. from the simulator) validate a FORMATS.md plots table and produce a batch;
the tracker takes the batch as it is and never re-validates it.

Units: time s, range m, azimuth and elevation rad (azimuth clockwise from north),
range rate m/s, Mode C altitude m.  Identity codes (``-1`` = absent):

* ``mode3a`` — the 4-octal-digit Mode 3/A code as an integer (``int(code, 8)``);
* ``mode_s`` — the 24-bit ICAO address as an integer (``int(icao24, 16)``);
* ``iff`` — index into :data:`IFF_VALUES`.

:func:`decode_mode3a`, :func:`decode_icao24` and :func:`decode_iff` give the text back (as
pandas arrays; :func:`mode3a_text`, :func:`icao24_text` and :func:`iff_text` as pyarrow arrays).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

FT_TO_M = 0.3048
IFF_VALUES = ("friend", "foe", "undetermined")
PLATFORM_COLUMNS = tuple(f"platform_{c}" for c in ("x", "y", "z", "vx", "vy", "vz"))


@dataclass
class PlotBatch:
    """Plots as arrays; ``sensor`` indexes the sensor set, ``row`` is the row in the whole input."""

    time: np.ndarray
    sensor: np.ndarray
    range_m: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    range_rate: np.ndarray
    mode_c_m: np.ndarray
    mode3a: np.ndarray
    mode_s: np.ndarray
    iff: np.ndarray
    platform: np.ndarray
    row: np.ndarray

    def __len__(self) -> int:
        return len(self.time)

    def take(self, index) -> "PlotBatch":
        return PlotBatch(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def concat(parts: list["PlotBatch"]) -> "PlotBatch":
        return PlotBatch(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PlotBatch)})

    @staticmethod
    def empty() -> "PlotBatch":
        nan = np.zeros(0)
        codes = np.zeros(0, np.int32)
        return PlotBatch(nan, np.zeros(0, np.int16), nan, nan, nan, nan, nan, codes, codes,
                         np.zeros(0, np.int8), np.zeros((0, 6)), np.zeros(0, np.int64))

    @staticmethod
    def from_frame(frame: pd.DataFrame, sensor_names: list[str] | None, is_3d: list[bool] | None = None,
                   source: str = "plots", first_row: int = 0, check: bool = True) -> "PlotBatch":
        """Convert a plots table (docs/formats.md); bad values raise ValueError naming the row and column.

        ``first_row`` is the row number of the frame's first row in the whole input (chunks).
        Checked: required columns, unknown sensors, malformed identity codes and, unless
        ``check`` is False (the io readers have validated the table already), non-finite
        times, ranges and azimuths, negative ranges and 3-D radar plots without elevation.
        """
        count = len(frame)
        missing = [c for c in ("time", "sensor", "range_m", "azimuth_deg") if c not in frame.columns]
        if missing:
            raise ValueError(f"{source}: missing required column(s) {missing}; found {list(frame.columns)}")
        if sensor_names is None:
            sensor_index = np.zeros(count, dtype=np.int16)
        else:
            codes, uniques = _dictionary(frame["sensor"])
            lookup = {name: i for i, name in enumerate(sensor_names)}
            unknown = [k for k, u in enumerate(uniques) if u not in lookup]
            if unknown:
                first = first_row + int(np.flatnonzero(codes == unknown[0])[0])
                raise ValueError(f"{source}, row {first}, column sensor: unknown sensor {uniques[unknown[0]]!r} "
                                 f"(sensors.json has: {', '.join(sensor_names)})")
            sensor_index = (np.array([lookup[u] for u in uniques], dtype=np.int16)[codes] if count
                            else np.zeros(0, np.int16))

        def numeric(column: str, scale: float = 1.0) -> np.ndarray:
            if column not in frame.columns:
                return np.full(count, np.nan)
            return frame[column].to_numpy(dtype=float, na_value=np.nan) * scale

        batch = PlotBatch(
            time=numeric("time"), sensor=sensor_index, range_m=numeric("range_m"),
            azimuth=np.radians(numeric("azimuth_deg")), elevation=np.radians(numeric("elevation_deg")),
            range_rate=numeric("range_rate_mps"), mode_c_m=numeric("mode_c_ft", FT_TO_M),
            mode3a=_codes(frame, "mode3a", 8, source, first_row),
            mode_s=_codes(frame, "mode_s", 16, source, first_row),
            iff=_iff_codes(frame, source, first_row),
            platform=(np.column_stack([numeric(c) for c in PLATFORM_COLUMNS])
                      if any(c in frame.columns for c in PLATFORM_COLUMNS) else np.full((count, 6), np.nan)),
            row=first_row + np.arange(count, dtype=np.int64),
        )
        if not check:
            return batch
        problems = [
            ("time", ~np.isfinite(batch.time), "value is not a finite number"),
            ("range_m", ~np.isfinite(batch.range_m), "value is not a finite number"),
            ("range_m", batch.range_m < 0, "value is negative"),
            ("azimuth_deg", ~np.isfinite(batch.azimuth), "value is not a finite number"),
        ]
        if is_3d is not None and count:
            flags = np.asarray(is_3d, dtype=bool)[sensor_index]
            problems.append(("elevation_deg", flags & ~np.isfinite(batch.elevation), "value is missing for a plot of a 3-D radar"))
        for name, bad, what in problems:
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                given = frame[name].iloc[row] if name in frame.columns else None
                shown = "" if given is None else f" (got {given})"
                raise ValueError(f"{source}, row {first_row + row}, column {name}: {what}{shown}")
        return batch


def _text(frame: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray]:
    values = frame[column].astype(object).to_numpy()
    present = ~pd.isna(values)
    return values, present


def _dictionary(column: pd.Series) -> tuple[np.ndarray, list[str]]:
    """Dictionary codes of a text column and its distinct values (pyarrow hashing; null as "None")."""
    import pyarrow as pa

    values = pa.array(column.astype("str"), type=pa.string(), from_pandas=True)
    if isinstance(values, pa.ChunkedArray):
        values = values.combine_chunks()
    encoded = values.fill_null("None").dictionary_encode()
    return encoded.indices.to_numpy(zero_copy_only=False), encoded.dictionary.to_pylist()


def _codes(frame: pd.DataFrame, column: str, base: int, source: str, first_row: int) -> np.ndarray:
    """Integer codes of a text column, parsing each distinct text once (pyarrow dictionary)."""
    import pyarrow as pa

    if column not in frame.columns:
        return np.full(len(frame), -1, dtype=np.int32)
    values = pa.array(frame[column].astype("str"), type=pa.string(), from_pandas=True)
    if isinstance(values, pa.ChunkedArray):  # an Arrow-backed column may come in several chunks
        values = values.combine_chunks()
    encoded = values.dictionary_encode()
    texts = encoded.dictionary.to_pylist()
    parsed = np.empty(len(texts) + 1, dtype=np.int32)
    parsed[-1] = -1  # absent
    for k, text in enumerate(texts):
        try:
            parsed[k] = int(text, base)
        except ValueError:
            indices = encoded.indices.to_numpy(zero_copy_only=False)
            row = first_row + int(np.flatnonzero(indices == k)[0])
            kind = "an octal" if base == 8 else "a hexadecimal"
            raise ValueError(f"{source}, row {row}, column {column}: {text!r} is not {kind} code") from None
    indices = encoded.indices.fill_null(len(texts)).to_numpy(zero_copy_only=False)
    return parsed[indices]


def _iff_codes(frame: pd.DataFrame, source: str, first_row: int) -> np.ndarray:
    out = np.full(len(frame), -1, dtype=np.int8)
    if "iff" not in frame.columns:
        return out
    values, present = _text(frame, "iff")
    lookup = {v: i for i, v in enumerate(IFF_VALUES)}
    coded = np.array([lookup.get(str(v), -2) for v in values[present]], dtype=np.int8)
    if (coded == -2).any():
        row = first_row + int(np.flatnonzero(present)[np.flatnonzero(coded == -2)[0]])
        raise ValueError(f"{source}, row {row}, column iff: expected one of {IFF_VALUES}")
    out[present] = coded
    return out


def decode_mode3a(codes: np.ndarray):
    return _as_pandas_text(mode3a_text(codes))


def decode_icao24(codes: np.ndarray):
    return _as_pandas_text(icao24_text(codes))


def decode_iff(codes: np.ndarray):
    return _as_pandas_text(iff_text(codes))


def mode3a_text(codes: np.ndarray):
    """:func:`decode_mode3a` as dictionary-encoded pyarrow text (what a table writer takes)."""
    return _decode(codes, "{:04o}")


def icao24_text(codes: np.ndarray):
    """:func:`decode_icao24` as dictionary-encoded pyarrow text."""
    return _decode(codes, "{:06x}")


def iff_text(codes: np.ndarray):
    """:func:`decode_iff` as dictionary-encoded pyarrow text."""
    return _decode(codes, None)


def _as_pandas_text(values):
    return pd.array(values.dictionary_decode(), dtype="str")


def _decode(codes: np.ndarray, form: str | None):
    """Text of integer codes as a pyarrow dictionary array (null where the code is -1).

    Each distinct code is formatted once (pyarrow dictionary encoding), so decoding a drain's
    rows costs a hash pass, not a Python call per row; a Parquet writer stores the
    dictionary as it is, without hashing the texts again.
    """
    import pyarrow as pa

    codes = np.asarray(codes, dtype=np.int32)
    encoded = pa.array(codes, mask=codes < 0).dictionary_encode()
    values = encoded.dictionary.to_numpy().tolist()
    texts = [IFF_VALUES[c] for c in values] if form is None else [form.format(c) for c in values]
    return pa.DictionaryArray.from_arrays(encoded.indices, pa.array(texts, type=pa.string()))

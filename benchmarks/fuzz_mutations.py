"""Malformed inputs for the fuzz suite (issue 6, item 8): four families of mutated files.

Every case starts from one small valid input (the "crossing" simulation cut to
:data:`BASE_ROWS` plots, its ``sensors.json``) and applies one to three seeded mutations:

* ``plot_values``: values in the plot table (NaN, inf, huge, negative, wrong type, swapped,
  missing or duplicated columns, unit mistakes, time going backwards, unknown sensors,
  extreme identity codes), written as Parquet or CSV;
* ``csv_text``: bytes of the CSV text (flips, truncation, invalid UTF-8, stray quotes,
  separators, BOM, CRLF, NUL bytes) and damaged gzip streams for ``.csv.gz``;
* ``parquet_bytes``: byte flips, truncation, damaged footers and metadata;
* ``sensors_json``: JSON-level (wrong types, missing keys, NaN, huge or deep values, unknown
  types, duplicated names, empty lists) and text-level mutations of ``sensors.json``.

A case is rebuilt from ``(family, seed, index)`` alone (:func:`make_case`), so a failing case
can be replayed.  ``rows_in_file`` is what the reader must account for: rows read plus rows
skipped must equal it, else the run lost data silently.
"""

from __future__ import annotations

import copy
import csv
import gzip
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

FAMILIES = ("plot_values", "csv_text", "parquet_bytes", "sensors_json")
#: plots kept from the simulation: enough for tracks to form, few enough for ~10 ms a case
BASE_ROWS = 300


@dataclass(frozen=True)
class BaseInputs:
    """The valid inputs every case mutates."""

    plots: pd.DataFrame
    csv_bytes: bytes
    parquet_bytes: bytes
    sensors: dict


@dataclass
class FuzzCase:
    """One malformed input: the files to write and what a correct run must account for."""

    family: str
    seed: int
    index: int
    mutation: str
    plots_name: str
    plots_bytes: bytes
    sensors_bytes: bytes
    rows_in_file: int
    lenient: bool
    chunk_rows: int

    @property
    def replay(self) -> dict:
        return {"family": self.family, "seed": self.seed, "index": self.index, "mutation": self.mutation,
                "lenient": self.lenient, "chunk_rows": self.chunk_rows}


def make_base_inputs(folder: str | Path) -> BaseInputs:
    """Simulate the "crossing" scenario once and cut it to :data:`BASE_ROWS` plots."""
    from skytrack.app.simulate import run_simulation, write_simulation

    paths = write_simulation(run_simulation("crossing", seed=1), folder, "parquet")
    plots = pd.read_parquet(paths["plots"]).iloc[:BASE_ROWS].reset_index(drop=True)
    parquet = io.BytesIO()
    plots.to_parquet(parquet, index=False)
    return BaseInputs(plots=plots, csv_bytes=plots.to_csv(index=False).encode(), parquet_bytes=parquet.getvalue(),
                      sensors=json.loads(Path(paths["sensors"]).read_text()))


def case_rng(family: str, seed: int, index: int) -> np.random.Generator:
    """The generator of one case: ``SeedSequence(seed).spawn`` keyed by family and case index."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(FAMILIES.index(family), index)))


def make_case(base: BaseInputs, family: str, seed: int, index: int) -> FuzzCase:
    rng = case_rng(family, seed, index)
    build = {"plot_values": _plot_values_case, "csv_text": _csv_text_case, "parquet_bytes": _parquet_bytes_case,
             "sensors_json": _sensors_json_case}[family]
    plots_name, plots_bytes, sensors_bytes, rows, mutations = build(base, rng)
    return FuzzCase(family=family, seed=seed, index=index, mutation="; ".join(mutations), plots_name=plots_name,
                    plots_bytes=plots_bytes, sensors_bytes=sensors_bytes, rows_in_file=rows,
                    lenient=bool(rng.integers(2)), chunk_rows=int(rng.choice([64, 200, 200_000])))


def _pick(rng: np.random.Generator, options):
    return options[int(rng.integers(len(options)))]


def _sensors_text(sensors: dict) -> bytes:
    return json.dumps(sensors, indent=2).encode()


# ---------------------------------------------------------------- plot values

ODD_VALUES = (math.nan, math.inf, -math.inf, 1e308, -1e308, -1.0, 0.0, 5e-324, 2**63 - 1, -(2**63), 1e20,
              "abc", "", " ", "1,5", "0x1F", "nan", "∞", True, None, "radar1", "12:00:00", "1e400")
IDENTITY_VALUES = ("7777", "8888", "0000", "77777", "-1", "1e20", "ZZZZ", "ffffff", "FFFFFFFF", "0", "",
                   "zzzzzz", "abcdef0", str(2**64), "1.5", "\x00", "α")
SENSOR_VALUES = ("radar9", "", " radar1", "RADAR1", "radar1 ", "x" * 10_000, "α", "null", "nan", "0")


def _set_values(df: pd.DataFrame, rng) -> str:
    column = _pick(rng, list(df.columns))
    rows = rng.choice(len(df), size=min(len(df), int(rng.integers(1, 6))), replace=False) if len(df) else []
    pool = IDENTITY_VALUES if column in ("mode3a", "mode_s", "iff") else (
        SENSOR_VALUES if column == "sensor" else ODD_VALUES)
    value = _pick(rng, pool)
    values = df[column].astype(object)
    values.iloc[rows] = [value] * len(rows)
    df[column] = values
    return f"set {column}[{','.join(map(str, rows))}]={value!r:.40}"


def _swap_columns(df: pd.DataFrame, rng) -> str:
    a, b = rng.choice(df.columns, size=2, replace=False)
    df.rename(columns={a: b, b: a}, inplace=True)
    return f"swap columns {a}<->{b}"


def _drop_column(df: pd.DataFrame, rng) -> str:
    column = _pick(rng, list(df.columns))
    df.drop(columns=[column], inplace=True)
    return f"drop column {column}"


def _unit_mistake(df: pd.DataFrame, rng) -> str:
    column, factor = _pick(rng, [("range_m", 1e-3), ("range_m", 1852.0), ("azimuth_deg", math.pi / 180),
                                 ("azimuth_deg", 400 / 360), ("time", 1e3), ("time", 1e-3), ("time", 1e9),
                                 ("elevation_deg", math.pi / 180), ("mode_c_ft", 0.3048), ("mode_c_ft", 100.0)])
    if column in df:
        df[column] = pd.to_numeric(df[column], errors="coerce") * factor
    return f"scale {column} by {factor:g}"


def _time_backwards(df: pd.DataFrame, rng) -> str:
    if len(df) < 2 or "time" not in df:
        return "time backwards (no rows or no time column)"
    start = int(rng.integers(0, len(df) - 1))
    stop = int(rng.integers(start + 1, len(df) + 1))
    how = _pick(rng, ["reverse", "shift", "negative"])
    times = pd.to_numeric(df["time"], errors="coerce").to_numpy(dtype=float, copy=True)
    if how == "reverse":
        times[start:stop] = times[start:stop][::-1]
    elif how == "shift":
        times[start:stop] -= float(rng.uniform(1, 1e4))
    else:
        times[start:stop] = -times[start:stop]
    df["time"] = times
    return f"time {how} rows {start}:{stop}"


def _duplicate_rows(df: pd.DataFrame, rng) -> str:
    rows = rng.choice(len(df), size=min(len(df), int(rng.integers(1, 20))), replace=False) if len(df) else []
    return f"repeat {len(rows)} rows", df.iloc[sorted(rows)]


def _plot_values_case(base: BaseInputs, rng):
    df = base.plots.copy()
    mutations, repeated = [], []
    for _ in range(int(rng.integers(1, 4))):
        kind = _pick(rng, ["set", "set", "set", "swap", "drop", "units", "backwards", "repeat", "cut", "empty"])
        if kind == "repeat":
            text, extra = _duplicate_rows(df, rng)
            repeated.append(extra)
            mutations.append(text)
            continue
        if kind == "cut":
            keep = int(rng.integers(0, len(df) + 1))
            df = df.iloc[:keep].reset_index(drop=True)
            mutations.append(f"keep {keep} rows")
            continue
        if kind == "empty":
            df = df.iloc[:0]
            mutations.append("no rows")
            continue
        if df.shape[1] < 2:
            continue
        action = {"set": _set_values, "swap": _swap_columns, "drop": _drop_column, "units": _unit_mistake,
                  "backwards": _time_backwards}[kind]
        mutations.append(action(df, rng))
    if repeated:
        df = pd.concat([df, *[extra[extra.columns.intersection(df.columns)] for extra in repeated]],
                       ignore_index=True)
    duplicate = df.shape[1] > 0 and rng.random() < 0.1
    if duplicate:
        mutations.append(f"duplicate column {df.columns[-1]}")
    as_csv = rng.random() < 0.5
    data = _plots_as_csv(df, duplicate) if as_csv else _plots_as_parquet(df, duplicate)
    return ("plots.csv" if as_csv else "plots.parquet"), data, _sensors_text(base.sensors), len(df), mutations


def _plots_as_csv(df: pd.DataFrame, duplicate: bool) -> bytes:
    if duplicate:
        df = pd.concat([df, df.iloc[:, -1:]], axis=1)
    return df.to_csv(index=False).encode("utf-8", "surrogatepass")


def _plots_as_parquet(df: pd.DataFrame, duplicate: bool) -> bytes:
    arrays, names = [], []
    for name in df.columns:
        try:
            arrays.append(pa.array(df[name].to_numpy() if df[name].dtype != object else df[name].tolist(),
                                   from_pandas=True))
        except (pa.ArrowInvalid, pa.ArrowTypeError, OverflowError):
            # a column of mixed types cannot be one Arrow type: a file writer would store it as text
            arrays.append(pa.array([None if v is None else str(v) for v in df[name].tolist()]))
        names.append(str(name))
    if duplicate and arrays:
        arrays.append(arrays[-1])
        names.append(names[-1])
    sink = io.BytesIO()
    pq.write_table(pa.Table.from_arrays(arrays, names=names) if arrays else pa.table({}), sink)
    return sink.getvalue()


# ---------------------------------------------------------------- CSV text

def _flip_bytes(data: bytearray, rng, count: int, start: int = 0) -> str:
    offsets = rng.integers(start, max(len(data), start + 1), size=count) if data else []
    for offset in offsets:
        if offset < len(data):
            data[offset] = int(rng.integers(0, 256))
    return f"flip bytes at {','.join(map(str, sorted(offsets)))}"


def _insert(data: bytearray, rng, token: bytes, name: str) -> str:
    offset = int(rng.integers(0, len(data) + 1))
    data[offset:offset] = token
    return f"insert {name} at {offset}"


def _mutate_csv_bytes(data: bytearray, rng) -> str:
    kind = _pick(rng, ["flip", "truncate", "utf8", "quote", "separator", "drop_separator", "bom", "crlf", "nul",
                       "blank", "cr", "long_line"])
    if kind == "flip":
        return _flip_bytes(data, rng, int(rng.integers(1, 11)))
    if kind == "truncate":
        offset = int(rng.integers(0, len(data) + 1))
        del data[offset:]
        return f"truncate at {offset}"
    if kind == "utf8":
        return _insert(data, rng, _pick(rng, [b"\xff\xfe", b"\xc3", b"\xe2\x82", b"\xed\xa0\x80", b"\x80"]),
                       "invalid UTF-8")
    if kind == "quote":
        return _insert(data, rng, b'"', "stray quote")
    if kind == "separator":
        return _insert(data, rng, b",", "extra separator")
    if kind == "drop_separator":
        commas = [i for i, byte in enumerate(data) if byte == ord(",")]
        if commas:
            del data[_pick(rng, commas)]
        return "remove a separator"
    if kind == "bom":
        data[0:0] = b"\xef\xbb\xbf"
        return "UTF-8 BOM"
    if kind == "crlf":
        data[:] = bytes(data).replace(b"\n", b"\r\n")
        return "CRLF line ends"
    if kind == "nul":
        return _insert(data, rng, b"\x00", "NUL byte")
    if kind == "blank":
        return _insert(data, rng, b"\n\n", "blank lines")
    if kind == "cr":
        return _insert(data, rng, b"\r", "lone CR")
    return _insert(data, rng, b"9" * 100_000, "100 kB number")


def count_csv_records(data: bytes) -> int:
    """Data records of a CSV text as Python's csv module splits them (blank lines excluded)."""
    csv.field_size_limit(2**31 - 1)  # the "100 kB number" mutation exceeds the default limit
    # a NUL is a character of its line, as for pyarrow: between the CR and LF of a CRLF it
    # makes a line of its own (a malformed one, skipped and counted by the reader)
    text = data.decode("utf-8", "replace").lstrip("\ufeff").replace("\x00", "\ufffd")
    reader = csv.reader(io.StringIO(text, newline=""), strict=False)
    records = sum(1 for record in reader if record)
    return max(records - 1, 0)  # minus the header


def _csv_text_case(base: BaseInputs, rng):
    data = bytearray(base.csv_bytes)
    mutations = [_mutate_csv_bytes(data, rng) for _ in range(int(rng.integers(1, 4)))]
    rows = count_csv_records(bytes(data))
    if rng.random() < 0.3:  # a .csv.gz whose compressed stream is damaged or cut
        packed = bytearray(gzip.compress(bytes(data), mtime=0))
        damage = _pick(rng, ["none", "truncate", "flip", "trailing"])
        if damage == "truncate":
            offset = int(rng.integers(0, len(packed)))
            del packed[offset:]
            mutations.append(f"gzip truncated at {offset}")
        elif damage == "flip":
            mutations.append("gzip " + _flip_bytes(packed, rng, int(rng.integers(1, 4))))
        elif damage == "trailing":
            packed += b"garbage"
            mutations.append("gzip trailing garbage")
        return "plots.csv.gz", bytes(packed), _sensors_text(base.sensors), rows, mutations
    return "plots.csv", bytes(data), _sensors_text(base.sensors), rows, mutations


# ---------------------------------------------------------------- Parquet bytes

def _parquet_bytes_case(base: BaseInputs, rng):
    data = bytearray(base.parquet_bytes)
    mutations = []
    for _ in range(int(rng.integers(1, 3))):
        kind = _pick(rng, ["flip", "flip_footer", "truncate", "footer_length", "zero", "append", "magic"])
        if kind == "flip":
            mutations.append(_flip_bytes(data, rng, int(rng.integers(1, 9))))
        elif kind == "flip_footer":
            mutations.append("footer " + _flip_bytes(data, rng, int(rng.integers(1, 5)), max(len(data) - 3000, 0)))
        elif kind == "truncate":
            offset = int(rng.integers(0, len(data) + 1))
            del data[offset:]
            mutations.append(f"truncate at {offset}")
        elif kind == "footer_length" and len(data) >= 8:
            length = int(_pick(rng, [0, 1, 7, 2**31 - 1, 2**32 - 1, len(data), int(rng.integers(0, len(data)))]))
            data[-8:-4] = length.to_bytes(4, "little")
            mutations.append(f"footer length {length}")
        elif kind == "zero":
            start = int(rng.integers(0, max(len(data), 1)))
            stop = start + int(rng.integers(1, 200))
            data[start:stop] = bytes(len(data[start:stop]))
            mutations.append(f"zero bytes {start}:{stop}")
        elif kind == "append":
            data += bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8))
            mutations.append("append garbage")
        elif kind == "magic" and len(data) >= 4:
            data[-4:] = b"PAR0"
            mutations.append("bad magic")
    return "plots.parquet", bytes(data), _sensors_text(base.sensors), len(base.plots), mutations


# ---------------------------------------------------------------- sensors.json

JSON_ODD_VALUES = ("text", "", [], {}, [1, 2], True, None, -1, 0, 1e308, -1e308, 2**70, math.nan, math.inf,
                   -math.inf, "NaN", "1e400", 1e-320)


def _json_paths(node, prefix=()):
    """Every key path of a JSON value (the root excluded)."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        yield prefix + (key,)
        yield from _json_paths(value, prefix + (key,))


def _parent(doc, path):
    for key in path[:-1]:
        doc = doc[key]
    return doc


def _mutate_sensors_doc(doc: dict, rng) -> tuple[str, str | None]:
    """One JSON-level mutation of ``doc`` in place; a raw text to splice in for values JSON cannot hold."""
    paths = list(_json_paths(doc))
    kind = _pick(rng, ["value", "value", "delete", "type", "duplicate", "empty", "unknown_key", "huge_int",
                       "deep", "huge_number", "root"])
    path = paths[int(rng.integers(len(paths)))] if paths else ()
    if kind == "value" and path:
        value = _pick(rng, JSON_ODD_VALUES)
        _parent(doc, path)[path[-1]] = value
        return f"{'/'.join(map(str, path))} = {value!r}", None
    if kind == "delete" and path:
        del _parent(doc, path)[path[-1]]
        return f"delete {'/'.join(map(str, path))}", None
    sensors = doc.get("sensors") if isinstance(doc.get("sensors"), list) else None
    if kind == "type" and sensors:
        sensor = _pick(rng, sensors)
        if isinstance(sensor, dict):
            sensor["type"] = _pick(rng, ["radar-4d", "sonar", "", "RADAR-2D", "adsb", "radar-3d", "mlat", 3])
            return f"sensor type {sensor['type']!r}", None
    if kind == "duplicate" and sensors:
        sensors.append(copy.deepcopy(_pick(rng, sensors)))
        return "duplicated sensor", None
    if kind == "empty":
        doc["sensors"] = []
        return "empty sensor list", None
    if kind == "unknown_key":
        doc[str(_pick(rng, ["extra", "sensor", "Sensors", "origin "]))] = 1
        return "unknown key", None
    if kind == "huge_int" and path:
        _parent(doc, path)[path[-1]] = "@@SPLICE@@"
        return f"{'/'.join(map(str, path))} = 5000-digit integer", "9" * 5000
    if kind == "deep" and path:
        depth = int(_pick(rng, [100, 1000, 100_000]))
        _parent(doc, path)[path[-1]] = "@@SPLICE@@"
        return f"{'/'.join(map(str, path))} nested {depth} deep", "[" * depth + "]" * depth
    if kind == "huge_number" and path:
        _parent(doc, path)[path[-1]] = "@@SPLICE@@"
        return f"{'/'.join(map(str, path))} = 1e400", "1e400"
    if kind == "root":
        replacement = _pick(rng, [[], "sensors", None, 3, [copy.deepcopy(doc)]])
        doc.clear()
        doc["@@ROOT@@"] = replacement
        return f"root is {type(replacement).__name__}", None
    return "no change", None


def _sensors_json_case(base: BaseInputs, rng):
    mutations = []
    if rng.random() < 0.75:
        doc = copy.deepcopy(base.sensors)
        splice = None
        for _ in range(int(rng.integers(1, 4))):
            text, raw = _mutate_sensors_doc(doc, rng)
            mutations.append(text)
            splice = raw or splice
            if "@@SPLICE@@" in json.dumps(doc) or "@@ROOT@@" in doc:
                break
        root = doc["@@ROOT@@"] if "@@ROOT@@" in doc else doc
        text = json.dumps(root, indent=2)  # NaN and Infinity are written as JSON extensions, as Python does
        text = text.replace('"@@SPLICE@@"', splice or "null")
        data = text.encode()
    else:
        data = bytearray(_sensors_text(base.sensors))
        mutations.append(_mutate_csv_bytes(data, rng))  # the same byte-level damage as for CSV text
        data = bytes(data)
    return "plots.parquet", base.parquet_bytes, data, len(base.plots), mutations

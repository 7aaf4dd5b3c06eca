"""Column schemas of the FORMATS.md tables (plots, adsb, truth, tracks, identity events, OpenSky input).

Dtype policy of every reader and writer (one rule for all tables):

- ``float`` columns are numpy ``float64``; a missing value is ``NaN``.
- ``int`` columns are numpy ``int64`` when required (``tracks.track_id``,
  ``truth.segment``) and pandas nullable ``Int64`` when optional (``plots.scan``,
  ``tracks.n_updates``, ``tracks.n_misses``), so a missing value is ``<NA>``, never a
  sentinel number.
- ``string`` columns, known or extra, use :data:`STRING_DTYPE`: pandas' own string dtype
  ``"str"`` (pyarrow storage, a missing value is ``NaN``; comparisons give plain numpy
  bools).  Identity columns (:data:`TEXT_COLUMNS`) are always read from CSV as text, so
  Mode 3/A ``"0123"`` keeps its leading zero.
- ``bool`` columns are numpy ``bool``.
- Readers keep absent optional columns absent (test with ``"mode3a" in df``); the
  exceptions are documented defaults (truth ``segment`` = 0, ``visible`` = True).
  :func:`skytrack.io.write_tracks` writes every :data:`TRACK_COLUMNS` column (nulls when
  unknown) because FORMATS.md lists them all for other tools.
- Known columns come first in FORMATS.md order, extra columns follow in their file order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pandas as pd

try:  # pandas >= 2.3: the NaN-semantics string dtype that pandas 3 uses by default
    STRING_DTYPE: object = pd.StringDtype(na_value=np.nan)
except TypeError:  # pragma: no cover - older pandas
    STRING_DTYPE = np.dtype(object)

Kind = Literal["float", "int", "string", "bool"]


@dataclass(frozen=True)
class Column:
    """One column of a table: name, kind, whether it must be present, unit.

    ``nullable`` (default: not ``required``) says whether a value may be missing; an
    integer column that cannot hold nulls is numpy ``int64``, otherwise ``Int64``.
    """

    name: str
    kind: Kind
    required: bool = False
    unit: str = ""
    nullable: bool | None = None

    @property
    def allows_null(self) -> bool:
        return (not self.required) if self.nullable is None else self.nullable

    @property
    def dtype(self) -> object:
        if self.kind == "float":
            return np.dtype("float64")
        if self.kind == "int":
            return pd.Int64Dtype() if self.allows_null else np.dtype("int64")
        if self.kind == "bool":
            return np.dtype("bool")
        return STRING_DTYPE


@dataclass(frozen=True)
class TableSchema:
    """The columns of one table, in FORMATS.md order."""

    name: str
    columns: tuple[Column, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.columns)

    @property
    def required(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.columns if c.required)

    @property
    def dtypes(self) -> dict[str, object]:
        return {c.name: c.dtype for c in self.columns}

    def __getitem__(self, name: str) -> Column:
        for column in self.columns:
            if column.name == name:
                return column
        raise KeyError(name)


def _f(name: str, unit: str = "", required: bool = False) -> Column:
    return Column(name, "float", required, unit)


def _s(name: str, required: bool = False) -> Column:
    return Column(name, "string", required)


PLOT_SCHEMA = TableSchema(
    "plots",
    (
        _f("time", "s", True),
        _s("sensor", True),
        _f("range_m", "m", True),
        _f("azimuth_deg", "deg", True),
        Column("scan", "int"),
        _f("elevation_deg", "deg"),
        _f("range_rate_mps", "m/s"),
        _s("mode3a"),
        _f("mode_c_ft", "ft"),
        _s("mode_s"),
        _s("iff"),
        _s("truth_id"),
    ),
)

# x/y/z or lat/lon/alt_m is required; the reader checks that alternative itself.
ADSB_SCHEMA = TableSchema(
    "adsb",
    (
        _f("time", "s", True),
        _s("icao24", True),
        _f("x", "m"),
        _f("y", "m"),
        _f("z", "m"),
        _f("lat", "deg"),
        _f("lon", "deg"),
        _f("alt_m", "m"),
        _f("sigma_m", "m"),
        _s("callsign"),
        _f("vx", "m/s"),
        _f("vy", "m/s"),
        _f("vz", "m/s"),
    ),
)

# Position x/y/z or lat/lon/alt_m is required (with an origin to convert); segment,
# velocity, the other position and visible get documented defaults when absent.
TRUTH_SCHEMA = TableSchema(
    "truth",
    (
        _f("time", "s", True),
        _s("target_id", True),
        Column("segment", "int", nullable=False),
        _f("x", "m"),
        _f("y", "m"),
        _f("z", "m"),
        _f("vx", "m/s"),
        _f("vy", "m/s"),
        _f("vz", "m/s"),
        _f("lat", "deg"),
        _f("lon", "deg"),
        _f("alt_m", "m"),
        Column("visible", "bool", nullable=False),
    ),
)

TRACK_SCHEMA = TableSchema(
    "tracks",
    (
        _f("time", "s", True),
        Column("track_id", "int", True),
        _f("x", "m", True),
        _f("y", "m", True),
        _f("z", "m"),
        _f("vx", "m/s"),
        _f("vy", "m/s"),
        _f("vz", "m/s"),
        _f("var_x", "m2"),
        _f("var_y", "m2"),
        _f("var_z", "m2"),
        _f("var_vx", "m2/s2"),
        _f("var_vy", "m2/s2"),
        _f("var_vz", "m2/s2"),
        _f("lat", "deg"),
        _f("lon", "deg"),
        _f("alt_m", "m"),
        _s("status"),
        Column("n_updates", "int"),
        Column("n_misses", "int"),
        _s("mode3a"),
        _s("icao24"),
        _s("callsign"),
        _s("iff"),
        _s("identity_source"),
        _f("identity_p"),
        _s("model_probs"),
    ),
)

IDENTITY_EVENT_SCHEMA = TableSchema(
    "identity events",
    (
        _f("time", "s", True),
        Column("track_id", "int", True),
        _s("field", True),
        _s("old"),
        _s("new"),
        _s("source"),
        _f("identity_p"),
    ),
)

PLOT_COLUMNS = PLOT_SCHEMA.names
PLOT_REQUIRED = PLOT_SCHEMA.required
ADSB_COLUMNS = ADSB_SCHEMA.names
TRUTH_COLUMNS = TRUTH_SCHEMA.names
TRACK_COLUMNS = TRACK_SCHEMA.names

#: OpenSky state-vector columns understood by :func:`skytrack.io.read_truth`
OPENSKY_COLUMNS = (
    "timestamp",
    "time",
    "icao24",
    "latitude",
    "longitude",
    "altitude",
    "geoaltitude",
    "altitude_m",
    "geoaltitude_m",
    "callsign",
    "squawk",
    "onground",
    "groundspeed",
    "track",
    "vertical_rate",
)

#: columns always read as text from CSV (identities keep leading zeros)
TEXT_COLUMNS = frozenset(
    {
        "sensor",
        "mode3a",
        "mode_s",
        "icao24",
        "iff",
        "identity_source",
        "truth_id",
        "target_id",
        "callsign",
        "squawk",
        "status",
        "model_probs",
    }
)

IFF_VALUES = ("friend", "foe", "undetermined")
TRACK_STATUS_VALUES = ("confirmed", "coasting")

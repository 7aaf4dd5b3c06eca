"""The tracks table and the identity-events table: their columns and vocabularies (one source
for the tracker's output and the io writers and readers; docs/formats.md)."""

from __future__ import annotations

import pandas as pd

TRACK_OUTPUT_COLUMNS = [
    "time", "track_id", "x", "y", "z", "vx", "vy", "vz",
    "var_x", "var_y", "var_z", "var_vx", "var_vy", "var_vz",
    "lat", "lon", "alt_m", "status", "n_updates", "n_misses",
    "mode3a", "icao24", "callsign", "iff", "identity_source", "identity_p", "model_probs",
]
INTEGER_COLUMNS = {"track_id", "n_updates", "n_misses"}
#: text columns the tracker fills (pandas "str" dtype) and those it leaves empty (object, all None)
TEXT_COLUMNS = {"status", "mode3a", "icao24", "iff", "identity_source"}
EMPTY_COLUMNS = {"callsign", "model_probs"}
#: ``identity_source`` and the identity events' ``source`` (``adsb`` and ``radar``: issue 9)
IDENTITY_SOURCES = ("mode_s", "adsb", "iff", "radar")
#: the identity events' ``field`` values
IDENTITY_EVENT_FIELDS = ("icao24", "callsign", "mode3a", "iff")
IDENTITY_EVENT_COLUMNS = ["time", "track_id", "field", "old", "new", "source", "identity_p"]


def covariance_columns(state_dim: int) -> list[str]:
    """``cov_i_j`` for the upper triangle (i <= j) of the state covariance, in state order."""
    return [f"cov_{i}_{j}" for i in range(state_dim) for j in range(i, state_dim)]


def empty_tracks(full_covariance: bool, state_dim: int) -> pd.DataFrame:
    """A tracks table without rows, with the dtypes of a full one (so chunks concatenate)."""
    columns = {
        c: pd.Series(dtype="int64" if c in INTEGER_COLUMNS else "str" if c in TEXT_COLUMNS
                     else object if c in EMPTY_COLUMNS else float)
        for c in TRACK_OUTPUT_COLUMNS
    }
    if full_covariance:
        for name in covariance_columns(state_dim):
            columns[name] = pd.Series(dtype=float)
    return pd.DataFrame(columns)

"""Structure-of-arrays track bank (DESIGN.md rule 1).

All live tracks are rows of the arrays below; there is no Python object per track.
New tracks are appended, deleted tracks are removed by compaction.  Identity attributes
(Mode 3/A, Mode S address, IFF) are small object arrays carried alongside; they are only
copied by fancy indexing, never looped over.
"""

from __future__ import annotations

import numpy as np

TENTATIVE = 0
CONFIRMED = 1

_NUMERIC_FIELDS = {
    "t": np.float64,  # time of the state
    "track_id": np.int64,
    "status": np.int8,
    "hit_bits": np.uint32,  # last expected observations, newest in bit 0 (1 = hit)
    "n_events": np.int32,  # expected observations so far (for M-of-N)
    "n_updates": np.int64,
    "n_misses": np.int64,  # consecutive misses
    "created": np.float64,
    "last_event": np.float64,  # end of the window of the latest hit or miss
    "confirmed_at": np.float64,
    "alt_m": np.float64,  # last Mode C altitude (m), NaN if none
    "z_hint": np.float64,  # ENU z of the last plot (2-D tracking, for lat/lon)
    "nis_avg": np.float64,  # smoothed normalised innovation squared (manoeuvre detector)
    "manoeuvring": np.bool_,  # psi of spec 000 S3: the manoeuvre process noise is in use
}
_OBJECT_FIELDS = ("mode3a", "icao24", "iff")


class TrackBank:
    """States ``x[N, n]``, covariances ``P[N, n, n]`` and per-track metadata arrays."""

    def __init__(self, state_dim: int):
        self.state_dim = state_dim
        self.x = np.zeros((0, state_dim))
        self.P = np.zeros((0, state_dim, state_dim))
        for name, dtype in _NUMERIC_FIELDS.items():
            setattr(self, name, np.zeros(0, dtype=dtype))
        for name in _OBJECT_FIELDS:
            setattr(self, name, np.zeros(0, dtype=object))

    def __len__(self) -> int:
        return len(self.t)

    def append(self, x: np.ndarray, P: np.ndarray, **fields) -> None:
        """Append ``len(x)`` tracks; ``fields`` gives metadata arrays (missing ones get defaults)."""
        count = len(x)
        if count == 0:
            return
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, P])
        defaults = {"alt_m": np.nan, "z_hint": np.nan, "confirmed_at": np.nan}
        for name, dtype in _NUMERIC_FIELDS.items():
            value = fields.get(name, defaults.get(name, 0))
            column = np.broadcast_to(np.asarray(value, dtype=dtype), (count,))
            setattr(self, name, np.concatenate([getattr(self, name), column]))
        for name in _OBJECT_FIELDS:
            value = fields.get(name)
            column = np.full(count, None, dtype=object) if value is None else np.asarray(value, dtype=object)
            setattr(self, name, np.concatenate([getattr(self, name), column]))

    def keep(self, mask: np.ndarray) -> None:
        """Remove the tracks where ``mask`` is False."""
        if mask.all():
            return
        self.x = self.x[mask]
        self.P = self.P[mask]
        for name in (*_NUMERIC_FIELDS, *_OBJECT_FIELDS):
            setattr(self, name, getattr(self, name)[mask])

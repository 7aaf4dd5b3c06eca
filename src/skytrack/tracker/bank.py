"""Structure-of-arrays track bank: the filter's opaque state plus metadata columns.

All live tracks are rows (DESIGN.md rule 1): ``state`` is whatever the filter family keeps
(:class:`~skytrack.filters.base.ArrayState`: one Gaussian, a mixture, a switch flag...), and
each metadata column is one array.  Identity is integer-coded (``-1`` = unknown; see
:mod:`skytrack.core.plots`).  Components may :meth:`register_column` columns of their own
(a track score, an identification accumulator); every column follows appends and deletions.
The bank saves to plain arrays and reloads (checkpoints of a live tracker).
"""

from __future__ import annotations

import numpy as np

from skytrack.filters.base import ArrayState, GaussianState

TENTATIVE = 0
CONFIRMED = 1

#: name -> (dtype, default for new rows)
STANDARD_COLUMNS: dict[str, tuple[type, object]] = {
    "t": (np.float64, 0.0),  # time of the state
    "track_id": (np.int64, 0),
    "status": (np.int8, TENTATIVE),
    "hit_bits": (np.uint32, 0),  # last expected observations, newest in bit 0 (1 = hit)
    "n_events": (np.int32, 0),  # expected observations so far (for M-of-N)
    "n_updates": (np.int64, 0),
    "n_misses": (np.int64, 0),  # consecutive misses
    "created": (np.float64, 0.0),
    "last_event": (np.float64, 0.0),  # end of the window of the latest hit or miss
    "confirmed_at": (np.float64, np.nan),
    "alt_m": (np.float64, np.nan),  # last Mode C altitude (m)
    "z_hint": (np.float64, np.nan),  # ENU z of the last plot (2-D tracking, for lat/lon)
    "mode3a": (np.int32, -1),
    "icao24": (np.int32, -1),
    "iff": (np.int8, -1),
}


class TrackBank:
    """Filter state rows plus named column arrays (read as attributes: ``bank.status``)."""

    def __init__(self, filter) -> None:
        self.filter = filter
        n = filter.state_dim
        self.state: ArrayState = filter.initiate(np.zeros((0, n)), np.zeros((0, n, n)))
        self.columns: dict[str, np.ndarray] = {}
        self.defaults: dict[str, object] = {}
        for name, (dtype, default) in STANDARD_COLUMNS.items():
            self.register_column(name, dtype, default)

    def register_column(self, name: str, dtype, default) -> None:
        """Add a column (existing rows get ``default``)."""
        if name in self.columns:
            raise ValueError(f"track bank column {name!r} exists already")
        self.columns[name] = np.full(len(self.state), default, dtype=dtype)
        self.defaults[name] = default

    def __getattr__(self, name: str) -> np.ndarray:
        columns = self.__dict__.get("columns")
        if columns is not None and name in columns:
            return columns[name]
        raise AttributeError(f"track bank has no column {name!r}")

    def __len__(self) -> int:
        return len(self.state)

    def append(self, state: ArrayState, **values) -> None:
        """Append the rows of ``state``; ``values`` gives column values (others get defaults)."""
        count = len(state)
        if count == 0:
            return
        unknown = [k for k in values if k not in self.columns]
        if unknown:
            raise ValueError(f"track bank has no column(s) {unknown}")
        self.state = type(self.state).concat([self.state, state])
        for name, column in self.columns.items():
            value = values.get(name, self.defaults[name])
            new = np.broadcast_to(np.asarray(value, dtype=column.dtype), (count,))
            self.columns[name] = np.concatenate([column, new])

    def keep(self, mask: np.ndarray) -> None:
        """Remove the tracks where ``mask`` is False."""
        if mask.all():
            return
        self.state = self.state.take(mask)
        for name in self.columns:
            self.columns[name] = self.columns[name][mask]

    def estimate(self, rows=None) -> GaussianState:
        state = self.state if rows is None else self.state.take(rows)
        return state.estimate()

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Every array of the bank by name (``state.`` prefix for the filter state)."""
        arrays = {f"state.{k}": v for k, v in self.state.to_arrays().items()}
        arrays.update({f"column.{k}": v.copy() for k, v in self.columns.items()})
        return arrays

    def load_arrays(self, arrays: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`to_arrays` saved (the columns must be registered)."""
        state = {k[len("state."):]: v for k, v in arrays.items() if k.startswith("state.")}
        self.state = self.filter.state_type.from_arrays(state)
        for name in self.columns:
            key = f"column.{name}"
            if key not in arrays:
                raise ValueError(f"saved track bank lacks column {name!r}")
            self.columns[name] = np.array(arrays[key], dtype=self.columns[name].dtype)

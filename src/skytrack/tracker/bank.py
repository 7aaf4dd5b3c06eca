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
from skytrack.tracker.identity import IDENTITY_DEFAULT

TENTATIVE = 0
CONFIRMED = 1

#: name -> (dtype, default for new rows); a default that is an array makes a 2-D column (one such row per track)
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
    # replies seen and identity last shown in the events (layout: skytrack.tracker.identity)
    "identity": (np.int32, IDENTITY_DEFAULT),
    "score": (np.float64, 0.0),  # track score: log-likelihood ratio (skytrack.tracker.evidence)
    "score_max": (np.float64, 0.0),  # its largest value so far (deletion by the drop from it)
}


class TrackBank:
    """Filter state rows plus named column arrays (read as attributes: ``bank.status``).

    Arrays are kept with spare capacity (doubled when full), so that appending a window's new
    tracks and deleting lost ones move rows in place instead of reallocating every column;
    ``state`` and the columns are views of the first ``len(bank)`` rows.  Compiled kernels may
    work on the full arrays (:attr:`storage`, :attr:`column_storage`) and set :attr:`size`.
    """

    def __init__(self, filter, capacity: int = 64) -> None:
        self.filter = filter
        n = filter.state_dim
        self.size = 0
        self.storage: ArrayState = filter.initiate(np.zeros((capacity, n)), np.zeros((capacity, n, n)))
        self.column_storage: dict[str, np.ndarray] = {}
        self.defaults: dict[str, object] = {}
        for name, (dtype, default) in STANDARD_COLUMNS.items():
            self.register_column(name, dtype, default)

    @property
    def capacity(self) -> int:
        return len(self.storage)

    @property
    def state(self) -> ArrayState:
        """The live rows of the filter state (views: writes go to the bank)."""
        return self.storage.take(slice(0, self.size))

    @state.setter
    def state(self, value: ArrayState) -> None:
        self.size = 0
        self.reserve(len(value))
        self.storage.put(slice(0, len(value)), value)
        self.size = len(value)

    @property
    def columns(self) -> dict[str, np.ndarray]:
        return {name: column[: self.size] for name, column in self.column_storage.items()}

    def register_column(self, name: str, dtype, default) -> None:
        """Add a column (existing rows get ``default``; an array ``default`` is each row of a 2-D column)."""
        if name in self.column_storage:
            raise ValueError(f"track bank column {name!r} exists already")
        self.column_storage[name] = np.full((self.capacity, *np.shape(default)), default, dtype=dtype)
        self.defaults[name] = default

    def __getattr__(self, name: str) -> np.ndarray:
        storage = self.__dict__.get("column_storage")
        if storage is not None and name in storage:
            return storage[name][: self.__dict__["size"]]
        raise AttributeError(f"track bank has no column {name!r}")

    def __len__(self) -> int:
        return self.size

    def reserve(self, rows: int) -> None:
        """Make room for ``rows`` live rows (amortised doubling)."""
        if rows <= self.capacity:
            return
        capacity = max(rows, 2 * self.capacity)
        grown = type(self.storage).concat([self.storage, self.storage.take(np.zeros(capacity - self.capacity, np.intp))])
        self.storage = grown
        for name, column in self.column_storage.items():
            extra = np.full((capacity - len(column), *column.shape[1:]), self.defaults[name], dtype=column.dtype)
            self.column_storage[name] = np.concatenate([column, extra])

    def append(self, state: ArrayState, **values) -> None:
        """Append the rows of ``state``; ``values`` gives column values (others get defaults)."""
        count = len(state)
        if count == 0:
            return
        unknown = [k for k in values if k not in self.column_storage]
        if unknown:
            raise ValueError(f"track bank has no column(s) {unknown}")
        start = self.size
        self.reserve(start + count)
        rows = slice(start, start + count)
        self.storage.put(rows, state)
        for name, column in self.column_storage.items():
            column[rows] = values.get(name, self.defaults[name])
        self.size = start + count

    def keep(self, mask: np.ndarray) -> None:
        """Remove the tracks where ``mask`` is False (rows move up in place)."""
        if mask.all():
            return
        index = np.flatnonzero(mask)
        count = len(index)
        self.storage.put(slice(0, count), self.storage.take(index))
        for column in self.column_storage.values():
            column[:count] = column[index]
        self.size = count

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
        missing = [name for name in self.column_storage if f"column.{name}" not in arrays]
        if missing:
            raise ValueError(f"saved track bank lacks column(s) {missing}")
        self.state = self.filter.state_type.from_arrays(state)
        for name, column in self.column_storage.items():
            column[: self.size] = arrays[f"column.{name}"]

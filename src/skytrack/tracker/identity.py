"""Track identity: the replies a track has seen, its confidence, and its change history.

A track's identity attributes are its bank columns ``mode3a``, ``icao24`` and ``iff``
(integer-coded, ``-1`` unknown; :mod:`skytrack.core.plots`).  Spec 003 R14 / G8 fixes how they
follow the track's plots: the latest definite reply wins -- a plot's Mode 3/A code or Mode S
address replaces the track's when the plot has one, its IFF status when it is ``friend`` or
``foe``; a plot without a reply keeps the track's values (the carry-over prediction, eq. 12).
An ``undetermined`` reply only fills a track that has no status yet.

Beyond the spec (issue 8: "tracks carry their current identity, its confidence and its
history") each track keeps, in the bank's 2-D column ``identity`` (layout below):

* ``n_friend``, ``n_foe``: the definite IFF replies of its plots per status;
* per code kind (Mode 3/A, Mode S): the plots carrying the current code (``*_n``), the
  code shown before it (``*_alt``) and its plots (``*_alt_n``), and the plots of codes
  pushed out of those two slots (``*_other``);
* ``shown_*``: the values last written to the identity events (what a reader of the events
  knows), so that a change is found by comparing them with the bank's values.

Confidence (:func:`identity_probability`; docs/tracker.md "Identity"): each reply carries the
true value with probability ``1 - eps`` and otherwise one of the ``K - 1`` other values
(uniformly); with a uniform prior over the ``K`` values the posterior of the shown value is

    P = rho^a / (rho^a + rho^b + rho^o + K - 3),   rho = (1 - eps) (K - 1) / eps,

``a``, ``b``, ``o`` the plots of the shown value, of the previous one and of others.  Exact
when the track has seen at most two values (``o = 0``); with more, the others are counted as
one value, which can only lower P (a lower bound).  ``K = 2`` for the IFF status (friend,
foe; ``o = 0`` and the formula is ``1 / (1 + rho^(b - a))``), 4096 for Mode 3/A, 2^24 for Mode
S.  ``identity_p`` is the product of P over the attributes the track shows (independent
replies): the probability that all of them are right.  ``identity_source`` is ``mode_s``
when the track has a Mode S address from its plots, ``iff`` when it has a Mode 3/A code or a
definite IFF status, else null.

Events (:class:`IdentityEvents`): after every window the confirmed tracks whose ``mode3a``,
``icao24`` or ``iff`` differ from their ``shown_*`` values give one row per changed field
(``time`` = the track's latest plot, which brought the change; ``old`` null the first time).
A track takes at most one plot per window, so comparing once per window finds every change.
The compiled end of window (:func:`skytrack.tracker.window_kernels.initiate_manage`) lists
the changed rows as it compacts the bank; :func:`changed_rows` is the numpy reference.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from skytrack.core.plots import icao24_text, iff_text, mode3a_text
from skytrack.core.tracks import IDENTITY_EVENT_COLUMNS, IDENTITY_EVENT_FIELDS, IDENTITY_SOURCES

# layout of the bank's ``identity`` column (int32 per track)
(N_FRIEND, N_FOE, MODE3A_N, MODE3A_ALT, MODE3A_ALT_N, MODE3A_OTHER, ICAO24_N, ICAO24_ALT, ICAO24_ALT_N, ICAO24_OTHER,
 SHOWN_MODE3A, SHOWN_ICAO24, SHOWN_IFF) = range(13)
IDENTITY_WIDTH = 13
#: a new row's ``identity``: no reply, no code, nothing shown
IDENTITY_DEFAULT = np.array([0, 0, 0, -1, 0, 0, 0, -1, 0, 0, -1, -1, -1], dtype=np.int32)

#: number of values of each attribute (the K of the posterior)
IFF_STATUSES = 2
MODE3A_CODES = 4096
MODE_S_ADDRESSES = 2**24
#: per-reply error probability of the posterior when none is configured
DEFAULT_ERROR_P = 0.05

EVENT_FIELDS = IDENTITY_EVENT_FIELDS
#: indices into IDENTITY_SOURCES
SOURCE_MODE_S, SOURCE_IFF = IDENTITY_SOURCES.index("mode_s"), IDENTITY_SOURCES.index("iff")


# ---------------------------------------------------------------------------- replies of a hit
# The compiled writers call these two directly (numba inlines one level of inline="always"
# functions; a helper calling them cost 40 ns per hit instead of 2).
@njit(cache=True, nogil=True, inline="always")
def remember_code(identity, k, base, current, code):
    """R14 for a plot code ``code >= 0`` (Mode 3/A: ``base`` = MODE3A_N, Mode S: ICAO24_N) of
    track row ``k`` whose code is ``current``: counts it in the slots from ``base`` and returns
    the track's new code (the plot's: the latest reply wins)."""
    if code == current:
        identity[k, base] += 1
    elif code == identity[k, base + 1]:
        # back to the previous code: the two slots swap
        previous = identity[k, base + 2]
        identity[k, base + 1] = current
        identity[k, base + 2] = identity[k, base]
        identity[k, base] = previous + 1
    else:
        if current >= 0:
            identity[k, base + 3] += identity[k, base + 2]
            identity[k, base + 1] = current
            identity[k, base + 2] = identity[k, base]
        identity[k, base] = 1
    return code


@njit(cache=True, nogil=True, inline="always")
def remember_status(identity, k, iff, reply):
    """R14 for an IFF reply ``reply`` (-1 none) of track row ``k``: a definite one is counted and
    becomes the track's status; ``undetermined`` fills a track without one."""
    if reply == 0 or reply == 1:
        identity[k, N_FRIEND + reply] += 1
        iff[k] = reply
    elif reply == 2 and iff[k] < 0:
        iff[k] = 2


def initial_identity(reply_mode3a: np.ndarray, reply_mode_s: np.ndarray, reply_iff: np.ndarray) -> np.ndarray:
    """The ``identity`` rows of tracks started by plots carrying these replies ``[N, 13]``."""
    rows = np.tile(IDENTITY_DEFAULT, (len(reply_iff), 1))
    rows[:, N_FRIEND] = reply_iff == 0
    rows[:, N_FOE] = reply_iff == 1
    rows[:, MODE3A_N] = reply_mode3a >= 0
    rows[:, ICAO24_N] = reply_mode_s >= 0
    return rows


def remember_replies_reference(bank, rows: np.ndarray, reply_mode3a: np.ndarray, reply_mode_s: np.ndarray,
                               reply_iff: np.ndarray) -> None:
    """:func:`remember_status` and :func:`remember_code` for hits of distinct bank ``rows`` at
    once (numpy reference)."""
    identity = bank.identity
    definite = (reply_iff == 0) | (reply_iff == 1)
    hit_rows, status = rows[definite], reply_iff[definite].astype(np.intp)
    identity[hit_rows, N_FRIEND + status] += 1
    bank.iff[hit_rows] = status
    first = (reply_iff == 2) & (bank.iff[rows] < 0)
    bank.iff[rows[first]] = 2
    for column, base, replies in ((bank.mode3a, MODE3A_N, reply_mode3a), (bank.icao24, ICAO24_N, reply_mode_s)):
        has = replies >= 0
        hit_rows, code = rows[has], replies[has]
        current = column[hit_rows]
        same = code == current
        back = ~same & (code == identity[hit_rows, base + 1])
        new = ~same & ~back
        identity[hit_rows[same], base] += 1
        swap = hit_rows[back]
        previous = identity[swap, base + 2].copy()
        identity[swap, base + 1] = current[back]
        identity[swap, base + 2] = identity[swap, base]
        identity[swap, base] = previous + 1
        push = hit_rows[new & (current >= 0)]
        identity[push, base + 3] += identity[push, base + 2]
        identity[push, base + 1] = column[push]
        identity[push, base + 2] = identity[push, base]
        identity[hit_rows[new], base] = 1
        column[hit_rows] = code


# ---------------------------------------------------------------------------- confidence
#: a term of the posterior's denominator below e^-40 cannot change ``1 + terms`` in float64
_NEGLIGIBLE_LOG = -40.0


@njit(cache=True, nogil=True, inline="always")
def _shown_probability(a, b, other, log_rest, log_rho):
    """Posterior that the shown value is the true one (module docstring) in the overflow-safe
    form ``1 / (1 + rho^(b - a) + rho^(o - a) + (K - 3) rho^-a)``: ``a`` replies of the shown
    value, ``b`` of the previous one, ``other`` of others, ``log_rest`` = ln(K - 3) (None for
    K = 2: ``1 / (1 + rho^(b - a))``)."""
    # terms below e^-40 cannot change 1 + rest: skipped (most tracks have many agreeing replies)
    rest = 0.0
    exponent = (b - a) * log_rho
    if exponent > _NEGLIGIBLE_LOG:
        rest += np.exp(exponent)
    if log_rest is not None:
        exponent = (other - a) * log_rho
        if exponent > _NEGLIGIBLE_LOG:
            rest += np.exp(exponent)
        exponent = log_rest - a * log_rho
        if exponent > _NEGLIGIBLE_LOG:
            rest += np.exp(exponent)
    return 1.0 / (1.0 + rest)


_LOG_REST_MODE3A = float(np.log(MODE3A_CODES - 3.0))
_LOG_REST_MODE_S = float(np.log(MODE_S_ADDRESSES - 3.0))


@njit(cache=True, nogil=True)
def identity_rows(identity, mode3a, icao24, iff, rows, log_rho, source, p):
    """``identity_source`` codes and ``identity_p`` of bank ``rows`` into ``source``, ``p``;
    ``log_rho`` = :func:`log_rho` of IFF, Mode 3/A and Mode S (compiled; the output kernels
    call it on the reported rows)."""
    for c in range(len(rows)):
        r = rows[c]
        probability = 1.0
        status = iff[r]
        definite = status == 0 or status == 1
        if definite:
            probability *= _shown_probability(identity[r, N_FRIEND + status], identity[r, N_FOE - status], 0, None,
                                              log_rho[0])
        if mode3a[r] >= 0:
            probability *= _shown_probability(identity[r, MODE3A_N], identity[r, MODE3A_ALT_N],
                                              identity[r, MODE3A_OTHER], _LOG_REST_MODE3A, log_rho[1])
        if icao24[r] >= 0:
            probability *= _shown_probability(identity[r, ICAO24_N], identity[r, ICAO24_ALT_N],
                                              identity[r, ICAO24_OTHER], _LOG_REST_MODE_S, log_rho[2])
            source[c] = SOURCE_MODE_S
        elif mode3a[r] >= 0 or definite:
            source[c] = SOURCE_IFF
        else:
            source[c] = -1
        p[c] = probability if source[c] >= 0 else np.nan


def log_rho(error_p: float) -> np.ndarray:
    """``ln rho`` of IFF, Mode 3/A and Mode S: the log odds one agreeing reply adds,
    ``ln((1 - eps) (K - 1) / eps)``."""
    values = np.array([IFF_STATUSES, MODE3A_CODES, MODE_S_ADDRESSES], dtype=float)
    return np.log1p(-error_p) + np.log(values - 1.0) - np.log(error_p)


def identity_probability(identity: np.ndarray, mode3a: np.ndarray, icao24: np.ndarray, iff: np.ndarray,
                         error_p: float, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(identity_source, identity_p)`` of tracks (of ``rows``, default all): the source code per
    row (index into :data:`IDENTITY_SOURCES`, -1 = none) and the product of the shown attributes'
    posteriors (NaN without a source)."""
    rows = np.arange(len(iff)) if rows is None else np.asarray(rows, dtype=np.int64)
    source = np.empty(len(rows), np.int8)
    p = np.empty(len(rows))
    identity_rows(identity, mode3a, icao24, iff, rows, log_rho(error_p), source, p)
    return source, p


def source_text(source: np.ndarray):
    """The ``identity_source`` column as dictionary-encoded pyarrow text (null for -1)."""
    import pyarrow as pa

    return pa.DictionaryArray.from_arrays(pa.array(source, mask=source < 0), pa.array(IDENTITY_SOURCES))


# ---------------------------------------------------------------------------- events
def changed_rows(bank, confirmed: np.ndarray) -> np.ndarray:
    """Bank rows among the ``confirmed`` ones whose identity differs from what the events last
    showed (numpy reference of the check in :func:`skytrack.tracker.window_kernels.initiate_manage`)."""
    identity = bank.identity
    changed = ((identity[:, SHOWN_MODE3A] != bank.mode3a) | (identity[:, SHOWN_ICAO24] != bank.icao24)
               | (identity[:, SHOWN_IFF] != bank.iff))
    return np.flatnonzero(changed & confirmed)


#: the fields the tracker records (callsign: issue 9), their shown_* columns, field and source codes
_SHOWN_COLUMNS = [SHOWN_ICAO24, SHOWN_MODE3A, SHOWN_IFF]
_RECORDED_FIELDS = np.array([EVENT_FIELDS.index(name) for name in ("icao24", "mode3a", "iff")], np.int8)
_RECORDED_SOURCES = np.array([SOURCE_MODE_S, SOURCE_IFF, SOURCE_IFF], np.int8)


class IdentityEvents:
    """The identity-change rows found so far (docs/formats.md "identity events"), kept as
    arrays until :meth:`drain` makes them a table."""

    def __init__(self, error_p: float) -> None:
        self.error_p = error_p
        self.log_rho = log_rho(error_p)
        self.parts: list[dict[str, np.ndarray]] = []
        self.count = 0

    def record(self, bank, rows: np.ndarray) -> None:
        """One row per changed field of bank ``rows``; the rows then show their current values."""
        if len(rows) == 0:
            return
        identity = bank.identity[rows]
        # columns in the order of _RECORDED: icao24, mode3a, iff
        current = np.column_stack([bank.icao24[rows], bank.mode3a[rows], bank.iff[rows]]).astype(np.int32)
        shown = identity[:, _SHOWN_COLUMNS]
        row, column = np.nonzero(current != shown)
        p = np.empty(len(rows))
        identity_rows(bank.identity, bank.mode3a, bank.icao24, bank.iff, rows, self.log_rho, np.empty(len(rows), np.int8),
                      p)
        self.parts.append({
            "time": bank.t[rows][row], "track_id": bank.track_id[rows][row], "field": _RECORDED_FIELDS[column],
            "old": shown[row, column].astype(np.int64), "new": current[row, column].astype(np.int64),
            "source": _RECORDED_SOURCES[column], "identity_p": p[row],
        })
        self.count += len(row)
        identity[:, _SHOWN_COLUMNS] = current
        bank.identity[rows] = identity

    def drain(self):
        """The rows found since the last drain as a pyarrow Table in time order (ties: track
        id, then field), or ``None`` when there are none."""
        if not self.parts:
            return None
        parts, self.parts = self.parts, []
        columns = {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}
        order = np.lexsort((columns["field"], columns["track_id"], columns["time"]))
        columns = {name: values[order] for name, values in columns.items()}
        return events_table(columns)


def events_table(columns: dict[str, np.ndarray]):
    """The identity-events table of integer-coded columns (``field``, ``source`` indices;
    ``old``/``new`` codes of their field, -1 = null)."""
    import pyarrow as pa

    field = columns["field"]
    decoders = {"icao24": icao24_text, "mode3a": mode3a_text, "iff": iff_text}
    texts = {}
    for key in ("old", "new"):
        # each field's rows decoded at once, then put back in row order
        rows = [np.flatnonzero(field == index) for index in range(len(EVENT_FIELDS))]
        parts = [decoders[name](columns[key][part]).dictionary_decode() if name in decoders
                 else pa.nulls(len(part), pa.string()) for name, part in zip(EVENT_FIELDS, rows)]
        texts[key] = pa.concat_arrays(parts).take(pa.array(np.argsort(np.concatenate(rows), kind="stable")))
    p = columns["identity_p"]
    return pa.Table.from_arrays([
        pa.array(columns["time"], pa.float64()), pa.array(columns["track_id"], pa.int64()),
        pa.DictionaryArray.from_arrays(pa.array(field), pa.array(EVENT_FIELDS)).dictionary_decode(),
        texts["old"], texts["new"],
        pa.DictionaryArray.from_arrays(pa.array(columns["source"]), pa.array(IDENTITY_SOURCES)).dictionary_decode(),
        pa.array(p, pa.float64(), mask=np.isnan(p)),
    ], names=IDENTITY_EVENT_COLUMNS)

"""Identity-feature membership tables of spec 003: nationality (15), individual number (16).

A plot's IFF reply (nationality ``z_G`` and transponder number ``z_N``) is compared with the
track's last known values ``h_G``, ``h_N`` (the carry-over prediction (12)).  Each comparison
gives a factor ``mu`` in [0, 1] of the membership (13); the association rules use their
logarithms (:mod:`skytrack.association.identity_rules`).  The tables are data and
configurable (R8):

* ``g_table[(h_G, z_G)]`` — nine entries over ``friend``, ``foe``, ``undetermined``; the
  defaults are the paper's table (15).  A table with a missing pair or an entry outside
  [0, 1] is rejected; 0 means "forbidden" (``ln 0 = -inf``).
* ``n_match`` / ``n_mismatch`` — (16), defaults 0.9 / 0.1.

Missing values (spec 003 G7, R8): a plot without a reply counts as ``z_G = undetermined``
(``missing_iff="undetermined"``, the default) or scores ``mu_G = 1`` (``"neutral"``, the
ablation; an explicit "undetermined" reply still uses the table); a track with no definite
reply yet has ``h_G = undetermined``; ``mu_N = 1`` when the plot or the track has no number.

Further categorical features (the paper's primary-radar size or target class) are
:class:`CategoryTable` entries of ``extra``, with the same ``(h, z) -> mu`` form and the
same rule that a missing value on either side gives 1.  They are off by default.

Codes are those of :mod:`skytrack.core.plots`: IFF status 0 friend, 1 foe, 2 undetermined,
-1 no reply; numbers are integers, -1 = none.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from skytrack.core.plots import IFF_VALUES

FRIEND, FOE, UNDETERMINED = (IFF_VALUES.index(v) for v in ("friend", "foe", "undetermined"))
MISSING = -1
MISSING_IFF_RULES = ("undetermined", "neutral")

#: the paper's nationality table (15): (track's h_G, plot's z_G) -> mu_G
PAPER_G_TABLE: Mapping[tuple[str, str], float] = MappingProxyType({
    ("friend", "friend"): 0.8, ("friend", "undetermined"): 0.5, ("friend", "foe"): 0.2,
    ("foe", "friend"): 0.2, ("foe", "undetermined"): 0.5, ("foe", "foe"): 0.8,
    ("undetermined", "friend"): 0.2, ("undetermined", "undetermined"): 0.8, ("undetermined", "foe"): 0.2,
})


def _log_table(values: tuple[str, ...], table: Mapping[tuple[str, str], float], what: str) -> np.ndarray:
    """``ln table[(h, z)]`` as an array indexed by the value codes; every pair present, entries in [0, 1]."""
    missing = [(h, z) for h in values for z in values if (h, z) not in table]
    if missing:
        raise ValueError(f"{what}: the table has no entry for (track, plot) = {missing[0]!r}; "
                         f"it needs all {len(values) ** 2} pairs of {', '.join(values)}")
    unknown = [key for key in table if key[0] not in values or key[1] not in values]
    if unknown:
        raise ValueError(f"{what}: unknown value in table key {unknown[0]!r}; values are {', '.join(values)}")
    out = np.empty((len(values), len(values)))
    for (h, z), mu in table.items():
        if not (0.0 <= float(mu) <= 1.0):
            raise ValueError(f"{what}: entry {(h, z)!r} = {mu!r} is outside [0, 1]")
        with np.errstate(divide="ignore"):
            out[values.index(h), values.index(z)] = np.log(float(mu))
    return out


@dataclass(frozen=True)
class CategoryTable:
    """A further categorical feature: its values and ``table[(h, z)] -> mu``; missing (-1) on either side gives 1."""

    values: tuple[str, ...]
    table: Mapping[tuple[str, str], float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "_log", _log_table(tuple(self.values), self.table, "category table"))

    def log_mu(self, track_value: np.ndarray, plot_value: np.ndarray) -> np.ndarray:
        h = np.asarray(track_value, dtype=np.int64)
        z = np.asarray(plot_value, dtype=np.int64)
        known = (h >= 0) & (z >= 0)
        return np.where(known, self._log[np.maximum(h, 0), np.maximum(z, 0)], 0.0)


@dataclass(frozen=True)
class FeatureTables:
    """The membership tables (15), (16) and their missing-value rules; see the module docstring."""

    g_table: Mapping[tuple[str, str], float] = field(default_factory=lambda: PAPER_G_TABLE)
    n_match: float = 0.9
    n_mismatch: float = 0.1
    missing_iff: str = "undetermined"
    extra: Mapping[str, CategoryTable] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.missing_iff not in MISSING_IFF_RULES:
            raise ValueError(f"missing_iff must be one of {', '.join(MISSING_IFF_RULES)}, got {self.missing_iff!r}")
        for name in ("n_match", "n_mismatch"):
            value = float(getattr(self, name))
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} = {value!r} is outside [0, 1]")
        log_g = _log_table(IFF_VALUES, self.g_table, "g_table")
        # column 3: a plot without any reply
        no_reply = log_g[:, UNDETERMINED] if self.missing_iff == "undetermined" else np.zeros(len(IFF_VALUES))
        object.__setattr__(self, "log_g", np.column_stack([log_g, no_reply]))
        with np.errstate(divide="ignore"):
            object.__setattr__(self, "log_n", (float(np.log(self.n_match)), float(np.log(self.n_mismatch))))

    def log_mu_g(self, track_iff: np.ndarray, plot_iff: np.ndarray) -> np.ndarray:
        """``ln mu_G(h_G, z_G)`` per pair; a track without a definite status is undetermined."""
        h = np.asarray(track_iff, dtype=np.int64)
        z = np.asarray(plot_iff, dtype=np.int64)
        return self.log_g[np.where(h < 0, UNDETERMINED, h), np.where(z < 0, 3, z)]

    def log_mu_n(self, track_code: np.ndarray, plot_code: np.ndarray) -> np.ndarray:
        """``ln mu_N(h_N, z_N)`` per pair; 0 (``mu_N = 1``) when either side has no number."""
        h = np.asarray(track_code, dtype=np.int64)
        z = np.asarray(plot_code, dtype=np.int64)
        known = (h >= 0) & (z >= 0)
        return np.where(known, np.where(h == z, self.log_n[0], self.log_n[1]), 0.0)

    def log_mu_extra(self, track_values: Mapping[str, np.ndarray], plot_values: Mapping[str, np.ndarray],
                     size: int) -> np.ndarray:
        """Sum of ``ln mu`` of the extra categorical features (0 when there are none)."""
        total = np.zeros(size)
        for name, table in self.extra.items():
            if name not in track_values or name not in plot_values:
                raise ValueError(f"feature {name!r} has a table but no track or plot values were given")
            total += table.log_mu(track_values[name], plot_values[name])
        return total


#: the paper's tables (15), (16)
PAPER_TABLES = FeatureTables()
#: every factor 1: the fuzzy rule becomes coordinate-only nearest neighbour (R10 ``nn``, TV12)
UNIT_TABLES = FeatureTables(g_table={key: 1.0 for key in PAPER_G_TABLE}, n_match=1.0, n_mismatch=1.0,
                            missing_iff="neutral")
#: 0/1 factors: the fuzzy rule becomes the crisp veto rule (R10 ``crisp``, TV12)
CRISP_TABLES = FeatureTables(
    g_table={key: 0.0 if {key[0], key[1]} == {"friend", "foe"} else 1.0 for key in PAPER_G_TABLE},
    n_match=1.0, n_mismatch=0.0, missing_iff="neutral")

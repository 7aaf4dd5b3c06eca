"""The batched filter protocol: opaque structure-of-arrays states and pure filter steps.

A filter is a parameter object; its state is a set of arrays whose leading axis is rows
(tracks, identification pairs, IMM modes of a bank, Monte Carlo runs alike).  Every
family implements the same four steps over a batch of rows:

* ``initiate(x, P)`` — a state from Gaussian starting points;
* ``predict(state, dt, context)`` — pure, ``dt`` per row (negative extrapolates back);
* ``innovate(state, z, model, context)`` — :class:`Innovation`: ``nu``, ``S``, its
  Cholesky factor, ``d^2 = nu^T S^-1 nu`` (spec 000 R7), ``ln det S`` and the Gaussian
  log-likelihood, plus what ``update`` needs so it never recomputes them;
* ``update(state, z, innovation)`` — the corrected state and :class:`UpdateStats`.

Every state gives ``estimate()``: one Gaussian (x, P) per row whatever the family
(moment-matched for mixtures), which is what gating and output use; states also take and
put rows, concatenate, and save to / load from plain arrays (checkpoints).

Filters declare :class:`Capabilities` so that the conformance suite applies each
property only where it means something, and report diagnostics (gains, switch times,
mode probabilities) through one :class:`Recorder` channel.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from skytrack.core import linalg
from skytrack.filters.imm_kernels import moment_match_rows


# ---------------------------------------------------------------------------- states
def _names(cls) -> tuple[str, ...]:
    names = cls.__dict__.get("_field_names")
    if names is None:
        names = tuple(f.name for f in dataclasses.fields(cls))
        cls._field_names = names
    return names


@dataclass
class ArrayState:
    """Base of every filter state: dataclass fields that are arrays with rows first."""

    def __len__(self) -> int:
        return len(getattr(self, _names(type(self))[0]))

    def take(self, rows) -> "ArrayState":
        """The given rows (index array or boolean mask) as a new state."""
        return type(self)(*[getattr(self, name)[rows] for name in _names(type(self))])

    def put(self, rows, other: "ArrayState") -> None:
        """Overwrite the given rows with ``other``'s rows (in place)."""
        for name in _names(type(self)):
            getattr(self, name)[rows] = getattr(other, name)

    @classmethod
    def concat(cls, parts: list["ArrayState"]) -> "ArrayState":
        return cls(*[np.concatenate([getattr(p, name) for p in parts]) for name in _names(cls)])

    def copy(self) -> "ArrayState":
        return type(self)(*[getattr(self, name).copy() for name in _names(type(self))])

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Copies of the arrays by field name (``np.savez`` them to checkpoint a bank)."""
        return {name: np.array(getattr(self, name)) for name in _names(type(self))}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> "ArrayState":
        names = _names(cls)
        missing = [n for n in names if n not in arrays]
        if missing:
            raise ValueError(f"{cls.__name__}: saved arrays lack {missing}")
        return cls(**{n: np.array(arrays[n]) for n in names})

    def estimate(self) -> "GaussianState":  # pragma: no cover - interface
        raise NotImplementedError


@dataclass
class GaussianState(ArrayState):
    """One Gaussian per row: ``x[N, n]``, ``P[N, n, n]``."""

    x: np.ndarray
    P: np.ndarray

    def estimate(self) -> "GaussianState":
        return GaussianState(self.x, self.P)

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Replace the estimate of ``rows`` (e.g. by a two-point initialisation), in place."""
        self.x[rows] = x
        self.P[rows] = P


@dataclass
class MixtureState(ArrayState):
    """A Gaussian mixture per row: ``x[N, M, n]``, ``P[N, M, n, n]``, weights ``mu[N, M]``."""

    x: np.ndarray
    P: np.ndarray
    mu: np.ndarray

    def estimate(self) -> GaussianState:
        """Moment-matched Gaussian: ``x = sum mu_j x_j``, ``P = sum mu_j (P_j + d_j d_j^T)``
        (compiled for float arrays; :meth:`estimate_reference` is the numpy version it is tested against)."""
        if self.x.dtype == np.float64 and self.P.dtype == np.float64 and self.mu.dtype == np.float64:
            x, P = moment_match_rows(np.ascontiguousarray(self.x), np.ascontiguousarray(self.P),
                                     np.ascontiguousarray(self.mu))
            return GaussianState(x, P)
        return self.estimate_reference()

    def estimate_reference(self) -> GaussianState:
        """The numpy moment matching of :meth:`estimate`."""
        x = np.einsum("nm,nmi->ni", self.mu, self.x)
        d = self.x - x[:, None, :]
        P = np.einsum("nm,nmij->nij", self.mu, self.P + d[..., :, None] * d[..., None, :])
        return GaussianState(x, linalg.symmetrize(P))

    def reset_estimate(self, rows, x: np.ndarray, P: np.ndarray) -> None:
        """Every mode of ``rows`` takes the estimate ``x``, ``P``; mode probabilities are kept."""
        self.x[rows] = x[:, None, :]
        self.P[rows] = P[:, None, :, :]


# ---------------------------------------------------------------------------- results
@dataclass
class Innovation:
    """Innovation of a batch of rows against measurements ``z[K, m]``.

    ``m`` is the number of measured components per row (rows may pad unused components
    with a zero row of ``H`` and a zero innovation, which leaves ``d^2`` and the gain
    exact); ``predicted`` is the state the innovation was formed from, and ``extra``
    holds family-specific arrays (per-mode innovations of a mixture).
    """

    nu: np.ndarray
    S: np.ndarray
    chol: np.ndarray
    d2: np.ndarray
    logdet: np.ndarray
    loglik: np.ndarray
    m: np.ndarray
    H: np.ndarray
    R: np.ndarray
    predicted: ArrayState
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.d2)

    def take(self, rows) -> "Innovation":
        extra = {k: _take_extra(v, rows) for k, v in self.extra.items()}
        return Innovation(self.nu[rows], self.S[rows], self.chol[rows], self.d2[rows], self.logdet[rows],
                          self.loglik[rows], self.m[rows], self.H[rows], self.R[rows],
                          self.predicted.take(rows), extra)


def _take_extra(value, rows):
    if isinstance(value, list):
        return [item.take(rows) for item in value]
    if isinstance(value, np.ndarray):
        return value[rows]
    return value


@dataclass
class UpdateStats:
    """Per-row results of an update: normalised innovation squared per component and extras."""

    nis: np.ndarray
    extra: dict[str, Any] = field(default_factory=dict)


def measurement_terms(x: np.ndarray, z: np.ndarray, model, context: dict | None = None):
    """``(H, R, nu, m)`` of measurements ``z[K, m]`` against states ``x[K, n]`` through ``model``:
    the Jacobian, the noise, the innovation (formed by the model, which wraps angles and pads
    absent components) and the components measured per row.  A non-finite innovation is a
    ValueError, so no filter updates on NaN."""
    context = context or {}
    h, H = model.evaluate(x, context)
    R = model.noise(context)
    nu = model.residual(np.asarray(z, dtype=float), h, context)
    if not np.all(np.isfinite(nu)):
        raise ValueError("non-finite measurement or innovation")
    return H, R, nu, model.measured(context)


# ---------------------------------------------------------------------------- diagnostics
class Recorder:
    """The one diagnostics channel of filters: ``record(channel, rows, **values)``.

    The default recorder drops everything (``active`` is False, so filters may skip
    computing what only a recorder would want); :class:`ListRecorder` keeps the events.
    """

    active = False

    def record(self, channel: str, rows: np.ndarray, **values: np.ndarray) -> None:
        return None


class ListRecorder(Recorder):
    """Keeps every recorded event as ``(channel, rows, values)`` in ``events``."""

    active = True

    def __init__(self) -> None:
        self.events: list[tuple[str, np.ndarray, dict[str, np.ndarray]]] = []

    def record(self, channel: str, rows: np.ndarray, **values: np.ndarray) -> None:
        self.events.append((channel, np.asarray(rows).copy(), {k: np.asarray(v).copy() for k, v in values.items()}))

    def channel(self, name: str) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
        return [(rows, values) for channel, rows, values in self.events if channel == name]


# ---------------------------------------------------------------------------- protocol
@dataclass(frozen=True)
class Capabilities:
    """What a filter family guarantees, so that each conformance property applies where it means something.

    ``has_covariance``: the estimate carries a meaningful covariance.  ``gain_depends_on_r``:
    a huge measurement noise makes the update a no-op.  ``zero_dt_identity``: predicting by
    0 s returns the state unchanged (false for mixing models whose mixing step is not
    time-homogeneous).  ``estimate``: "gaussian" or "set" (set-membership filters).
    ``multiple_model``: the estimate is the moment-matched mixture of several models' filters
    (IMM, static bank), so it is conservative on a path of one model rather than chi-square
    consistent.  ``matched_consistent``: the filter is chi-square consistent on a motion model of
    its estimate's layout (its ``matched_motion`` or the one it was built with); False where the
    model it is consistent on has states the estimate does not carry (``ca-accel-adaptive``'s
    random-walk accelerations).
    """

    has_covariance: bool = True
    gain_depends_on_r: bool = True
    zero_dt_identity: bool = True
    estimate: str = "gaussian"
    multiple_model: bool = False
    matched_consistent: bool = True


class BatchFilter(ABC):
    """A filter family: parameters plus pure steps over :class:`ArrayState` batches.

    Optional attribute ``matched_motion``: a motion model (``F_batch``/``Q_batch``, e.g. a
    :class:`~skytrack.models.motion.MotionModel`) under which the filter is the optimal/consistent
    filter, when that is not the motion it was built with -- e.g. a manoeuvre detector built on an
    order-3 motion whose own model is its quiescent CV.  Consistency checks (the conformance suite's
    NEES) simulate truth from it when present.
    """

    kind: ClassVar[str] = ""
    capabilities: ClassVar[Capabilities] = Capabilities()
    state_type: ClassVar[type[ArrayState]] = GaussianState
    recorder: Recorder = Recorder()

    @property
    @abstractmethod
    def state_dim(self) -> int:
        """Length of the (estimate's) state vector."""

    @abstractmethod
    def initiate(self, x: np.ndarray, P: np.ndarray) -> ArrayState:
        """A state whose estimate is ``x[N, n]``, ``P[N, n, n]``."""

    @abstractmethod
    def predict(self, state: ArrayState, dt: np.ndarray, context: dict | None = None) -> ArrayState:
        """Prediction by ``dt`` seconds per row (pure)."""

    @abstractmethod
    def innovate(self, state: ArrayState, z: np.ndarray, model, context: dict | None = None) -> Innovation:
        """Innovation of ``z[K, m]`` against the rows of ``state`` through measurement ``model``."""

    @abstractmethod
    def update(self, state: ArrayState, z: np.ndarray, innovation: Innovation) -> tuple[ArrayState, UpdateStats]:
        """Measurement update of the rows of ``innovation.predicted``, reusing ``innovation``."""

    def transition_dt(self, dt) -> np.ndarray:
        steps = np.asarray(dt, dtype=float)
        if not np.all(np.isfinite(steps)):
            raise ValueError("time step must be finite")
        return steps

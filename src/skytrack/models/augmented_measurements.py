"""Measurement models of spec 002 R4 on augmented states, with sensor-bias parameters.

Channels (each declares its unit): Cartesian position ``x, y`` (m); range rate
``rdot = (p - p_s) . v / |p - p_s|`` (m/s) from a stationary sensor at ``p_s`` with Jacobian
``d rdot / dp = (v - rdot u) / r``, ``d rdot / dv = u`` (``u = (p - p_s) / r``); polar ``r`` (m)
and ``az`` (rad, clockwise from north, in [0, 2 pi), flagged angular so that innovations are
wrapped).  :func:`stack` concatenates channel sets; ``with_bias(channel)`` appends a bias
parameter b (unit of the channel, random walk) as the next state, ``y_c = h_c(x) + b``.
For these nonlinear channels the filter and the checker use H_k = dh/dx (gap G10).

States are ``[K, n]`` in spec 002 order, position and velocity found by component name
(``x, y, vx, vy``) in the :class:`~skytrack.models.augmented.AugmentedModel`.
:func:`augment_for_biases` extends a state model with the bias states a measurement needs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from skytrack.models.augmented import AugmentedModel

CHANNEL_UNITS = {"x": "m", "y": "m", "rdot": "m/s", "r": "m", "az": "rad"}
ANGULAR_CHANNELS = ("az",)
MEASUREMENT_KINDS = ("pos", "rdot", "polar")
KIND_CHANNELS = {"pos": ("x", "y"), "rdot": ("rdot",), "polar": ("r", "az")}


@dataclass(frozen=True)
class AugmentedMeasurement:
    """A set of channels measured on states of dimension ``state_dim``.

    ``position_index``/``velocity_index`` locate (x, y) and (vx, vy) in the state;
    ``sensor`` is the stationary sensor's (x, y) (m); ``biases`` maps a channel to the state
    index of its bias parameter.
    """

    channels: tuple[str, ...]
    state_dim: int
    position_index: tuple[int, int] = (0, 1)
    velocity_index: tuple[int, int] | None = (2, 3)
    sensor: tuple[float, float] = (0.0, 0.0)
    biases: tuple[tuple[str, int], ...] = ()

    def __post_init__(self):
        unknown = [c for c in self.channels if c not in CHANNEL_UNITS]
        if unknown:
            raise ValueError(f"unknown measurement channels {unknown}; known: {tuple(CHANNEL_UNITS)}")
        if len(set(self.channels)) != len(self.channels):
            raise ValueError(f"measurement channels must be unique, got {self.channels}")
        if "rdot" in self.channels and self.velocity_index is None:
            raise ValueError("range rate needs the velocity components vx, vy in the state")

    @property
    def dim(self) -> int:
        return len(self.channels)

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(CHANNEL_UNITS[c] for c in self.channels)

    @property
    def angular(self) -> np.ndarray:
        return np.array([c in ANGULAR_CHANNELS for c in self.channels])

    @property
    def bias_names(self) -> tuple[str, ...]:
        return tuple(f"b_{channel}" for channel, _ in self.biases)

    @property
    def bias_units(self) -> tuple[str, ...]:
        return tuple(CHANNEL_UNITS[channel] for channel, _ in self.biases)

    def with_bias(self, channel: str) -> "AugmentedMeasurement":
        """This measurement with a bias parameter on ``channel`` appended as state ``state_dim``."""
        if channel not in self.channels:
            raise ValueError(f"no channel {channel!r} to bias; channels: {self.channels}")
        if channel in dict(self.biases):
            raise ValueError(f"channel {channel!r} already has a bias")
        return replace(self, state_dim=self.state_dim + 1,
                       biases=self.biases + ((channel, self.state_dim),))

    def evaluate(self, states, jacobian: bool = True):
        """``h [K, m]`` and, with ``jacobian``, ``H [K, m, n]`` for states ``[K, n]`` (or ``[n]``)."""
        arr = np.asarray(states, dtype=float)
        single = arr.ndim == 1
        x = np.atleast_2d(arr)
        if x.shape[1] != self.state_dim:
            raise ValueError(f"states have {x.shape[1]} components, the measurement expects {self.state_dim}")
        k = len(x)
        pi = list(self.position_index)
        rel = x[:, pi] - np.asarray(self.sensor, dtype=float)
        r = np.hypot(rel[:, 0], rel[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            u = rel / r[:, None]
        h = np.zeros((k, self.dim))
        H = np.zeros((k, self.dim, self.state_dim))
        for row, channel in enumerate(self.channels):
            if channel in ("x", "y"):
                axis = 0 if channel == "x" else 1
                h[:, row] = x[:, pi[axis]]
                H[:, row, pi[axis]] = 1.0
            elif channel == "r":
                h[:, row] = r
                H[:, row, pi] = u
            elif channel == "az":
                h[:, row] = np.mod(np.arctan2(rel[:, 0], rel[:, 1]), 2.0 * np.pi)
                rho2 = r * r
                H[:, row, pi[0]] = rel[:, 1] / rho2
                H[:, row, pi[1]] = -rel[:, 0] / rho2
            else:  # rdot
                vi = list(self.velocity_index)
                v = x[:, vi]
                rdot = np.einsum("ki,ki->k", u, v)
                h[:, row] = rdot
                H[:, row, pi] = (v - rdot[:, None] * u) / r[:, None]
                H[:, row, vi] = u
        for channel, index in self.biases:
            row = self.channels.index(channel)
            h[:, row] += x[:, index]
            H[:, row, index] = 1.0
        if single:
            h, H = h[0], H[0]
        return (h, H) if jacobian else h

    def h(self, states) -> np.ndarray:
        return self.evaluate(states, jacobian=False)

    def H(self, states) -> np.ndarray:
        return self.evaluate(states)[1]


def measurement_for(model: AugmentedModel, kinds, sensor=(0.0, 0.0)) -> AugmentedMeasurement:
    """Channels of ``kinds`` (any of ``pos``, ``rdot``, ``polar``, in that order) on ``model``'s states."""
    kinds = (kinds,) if isinstance(kinds, str) else tuple(kinds)
    unknown = [kind for kind in kinds if kind not in MEASUREMENT_KINDS]
    if unknown:
        raise ValueError(f"unknown measurement kinds {unknown}; known: {MEASUREMENT_KINDS}")
    names = model.components
    velocity = (names.index("vx"), names.index("vy")) if {"vx", "vy"} <= set(names) else None
    channels = tuple(c for kind in kinds for c in KIND_CHANNELS[kind])
    return AugmentedMeasurement(channels=channels, state_dim=model.dim,
                                position_index=(names.index("x"), names.index("y")),
                                velocity_index=velocity, sensor=tuple(float(s) for s in sensor))


def augment_for_biases(model: AugmentedModel, measurement: AugmentedMeasurement,
                       variances=None) -> AugmentedModel:
    """``model`` with the bias states of ``measurement`` appended as random walks.

    ``variances`` are the per-step bias disturbance variances (default (1e-3 unit)^2 each, R14).
    """
    missing = measurement.state_dim - model.dim
    if missing < 0 or missing > len(measurement.biases):
        raise ValueError(f"measurement of state dimension {measurement.state_dim} does not fit model "
                         f"{model.name!r} of dimension {model.dim}")
    if missing == 0:
        return model
    new = measurement.biases[-missing:]
    names = tuple(f"b_{channel}" for channel, _ in new)
    units = tuple(CHANNEL_UNITS[channel] for channel, _ in new)
    variances = np.full(missing, 1e-6) if variances is None else variances
    return model.with_parameters(names, units, variances)


def one_step_sensitivity(model: AugmentedModel, measurement: AugmentedMeasurement, x_prev, T) -> np.ndarray:
    """Unwhitened ``S = H F h_a^T`` ``[K, m, p]`` with F at x(k-1) and H at phi(x(k-1)) (TV8)."""
    F = model.F(x_prev, T)
    H = measurement.H(model.phi(x_prev, T))
    return H @ model.G(x_prev, T, F=F)

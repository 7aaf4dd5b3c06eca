"""Augmented-state models of spec 002: state x = [x*, a] with model parameters a as random walks.

Implements spec 002 R1 (augmented-state model: component names and units, parameter index set
-> h_a, phi(x, T), F = d phi / dx, G = F h_a^T of eq. (4), per-step disturbance covariance V_w,
optional dependent-state noise Q_dep(T) for gap G11), R2 (``ct-omega``: coordinated turn with the
turn rate as a parameter, exact formulas and the small-|wT| series) and R3 (``ca-accel``:
constant acceleration as parameters).

Dynamics are given either as a discrete transition phi (``transition``), as a linear
``transition_matrix`` (phi(x) = F x), or as the drift f of eq. (1) (``drift``), integrated by
classical RK4 with ``n_sub = ceil(T / 0.1 s)`` equal sub-steps.  F is analytic when a
``jacobian`` is supplied, otherwise central differences with step
``delta_i = 6e-6 * max(1, |x_i|)``.

All functions take states ``[K, n]`` (or one state ``[n]``) and steps T as a scalar or ``[K]``.
State order is spec 002's ``[x, y, vx, vy, ...]`` (not MotionModel's per-axis order); this
model is distinct from :mod:`skytrack.models.turn`, whose turn rate is a fixed constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

#: RK4 sub-step ceiling of the drift route (R1 b), s
RK4_MAX_SUBSTEP = 0.1
#: relative central-difference step of R1 (delta_i = FD_STEP * max(1, |x_i|))
FD_STEP = 6e-6
#: |omega T| below which ct-omega uses its series (R2)
CT_SERIES_BELOW = 1e-3

Transition = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _rows(x) -> tuple[np.ndarray, bool]:
    """States as ``[K, n]`` and whether the caller gave a single state."""
    arr = np.asarray(x, dtype=float)
    return np.atleast_2d(arr), arr.ndim == 1


def _steps(T, k: int) -> np.ndarray:
    t = np.broadcast_to(np.asarray(T, dtype=float), (k,))
    if not np.all(np.isfinite(t)) or np.any(t < 0):
        raise ValueError(f"augmented model: steps T must be finite and >= 0, got {T}")
    return t


def rk4_substeps(T: float) -> int:
    """``ceil(T / 0.1 s)`` (at least 1); the tiny slack keeps 1.0/0.1 at 10 sub-steps."""
    return max(1, math.ceil(T / RK4_MAX_SUBSTEP - 1e-9))


def rk4_transition(drift: Callable[[np.ndarray], np.ndarray], x: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Classical RK4 solution of ``x' = f(x)`` over ``T`` (R1 b) for states ``[K, n]``, steps ``[K]``.

    Rows with the same T are integrated together; the sub-step count depends on T only.
    """
    out = np.empty_like(x)
    for step in np.unique(T):
        rows = T == step
        n_sub = rk4_substeps(float(step))
        h = float(step) / n_sub
        state = x[rows].copy()
        for _ in range(n_sub):
            k1 = drift(state)
            k2 = drift(state + 0.5 * h * k1)
            k3 = drift(state + 0.5 * h * k2)
            k4 = drift(state + h * k3)
            state = state + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out[rows] = state
    return out


def central_difference_jacobian(transition: Transition, x: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``d phi / dx`` ``[K, n, n]`` by central differences, ``delta_i = 6e-6 max(1, |x_i|)`` (R1)."""
    k, n = x.shape
    delta = FD_STEP * np.maximum(1.0, np.abs(x))  # [K, n]
    bump = delta[:, :, None] * np.eye(n)[None]  # [K, i, n]: row i perturbs component i
    plus = (x[:, None, :] + bump).reshape(k * n, n)
    minus = (x[:, None, :] - bump).reshape(k * n, n)
    t = np.repeat(T, n)
    diff = (transition(plus, t) - transition(minus, t)).reshape(k, n, n)  # [K, i, out]
    return np.swapaxes(diff / (2.0 * delta[:, :, None]), 1, 2)


@dataclass(frozen=True, eq=False)
class AugmentedModel:
    """Augmented-state model of R1.

    ``components``/``units`` name every state; ``parameters`` lists the parameter components
    (h_a has one unit row per parameter, in that order).  ``V_w`` is the per-step disturbance
    covariance (p x p, parameter units squared).  Exactly one of ``transition`` (phi(x, T) for
    ``[K, n]``, ``[K]``), ``transition_matrix`` (T ``[K]`` -> F ``[K, n, n]``, phi = F x) or
    ``drift`` (f(x) ``[K, n]``) is given; ``jacobian`` (x, T) -> ``[K, n, n]`` is optional.
    ``dependent_noise`` (T ``[K]`` -> ``[K, n, n]``) is Q_dep; None means 0 (the paper).
    """

    name: str
    components: tuple[str, ...]
    units: tuple[str, ...]
    parameters: tuple[str, ...]
    V_w: np.ndarray
    transition: Transition | None = None
    transition_matrix: Callable[[np.ndarray], np.ndarray] | None = None
    drift: Callable[[np.ndarray], np.ndarray] | None = None
    jacobian: Transition | None = None
    dependent_noise: Callable[[np.ndarray], np.ndarray] | None = None
    parameter_index: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if len(self.units) != len(self.components):
            raise ValueError(f"{self.name}: one unit per component is needed")
        if len(set(self.components)) != len(self.components):
            raise ValueError(f"{self.name}: component names must be unique, got {self.components}")
        unknown = [p for p in self.parameters if p not in self.components]
        if unknown:
            raise ValueError(f"{self.name}: parameters {unknown} are not components")
        routes = [r is not None for r in (self.transition, self.transition_matrix, self.drift)]
        if sum(routes) != 1:
            raise ValueError(f"{self.name}: give exactly one of transition, transition_matrix, drift")
        p = len(self.parameters)
        V_w = np.asarray(self.V_w, dtype=float).reshape(p, p)
        if not np.allclose(V_w, V_w.T) or np.any(np.linalg.eigvalsh(V_w) < 0):
            raise ValueError(f"{self.name}: V_w must be symmetric positive semi-definite")
        object.__setattr__(self, "V_w", V_w)
        object.__setattr__(self, "parameter_index",
                           np.array([self.components.index(p) for p in self.parameters], dtype=int))

    # ---------------------------------------------------------------- structure
    @property
    def dim(self) -> int:
        return len(self.components)

    @property
    def n_parameters(self) -> int:
        return len(self.parameters)

    @property
    def is_linear(self) -> bool:
        return self.transition_matrix is not None

    @property
    def h_a(self) -> np.ndarray:
        """Parameter selection matrix (p x n), unit rows, ``a = h_a x`` (eq. 2)."""
        h_a = np.zeros((self.n_parameters, self.dim))
        h_a[np.arange(self.n_parameters), self.parameter_index] = 1.0
        return h_a

    def unit_of(self, component: str) -> str:
        return self.units[self.components.index(component)]

    # ---------------------------------------------------------------- dynamics
    def _phi_rows(self, x: np.ndarray, t: np.ndarray) -> np.ndarray:
        if self.transition is not None:
            return np.asarray(self.transition(x, t), dtype=float)
        if self.transition_matrix is not None:
            return np.einsum("kij,kj->ki", self.transition_matrix(t), x)
        return rk4_transition(self.drift, x, t)

    def phi(self, x, T) -> np.ndarray:
        """Mean transition phi(x, T): ``[K, n]`` (or ``[n]`` for one state)."""
        rows, single = _rows(x)
        out = self._phi_rows(rows, _steps(T, len(rows)))
        return out[0] if single else out

    def F(self, x, T) -> np.ndarray:
        """``F = d phi / dx`` at x: ``[K, n, n]`` (analytic, linear, or central differences)."""
        rows, single = _rows(x)
        t = _steps(T, len(rows))
        if self.transition_matrix is not None:
            out = np.array(self.transition_matrix(t), dtype=float)
        elif self.jacobian is not None:
            out = np.asarray(self.jacobian(rows, t), dtype=float)
        else:
            out = central_difference_jacobian(self._phi_rows, rows, t)
        return out[0] if single else out

    def finite_difference_F(self, x, T) -> np.ndarray:
        """F by central differences even when an analytic Jacobian exists (for checks)."""
        rows, single = _rows(x)
        out = central_difference_jacobian(self._phi_rows, rows, _steps(T, len(rows)))
        return out[0] if single else out

    def G(self, x, T, F: np.ndarray | None = None) -> np.ndarray:
        """Disturbance transition ``G = F h_a^T`` (eq. 4): the parameter columns of F, ``[K, n, p]``."""
        F = self.F(x, T) if F is None else np.asarray(F, dtype=float)
        return F[..., :, self.parameter_index]

    def Q_dep(self, T) -> np.ndarray:
        """Dependent-state noise ``[K, n, n]`` (``[n, n]`` for scalar T); zero unless supplied (G11)."""
        scalar = np.ndim(T) == 0
        t = np.atleast_1d(np.asarray(T, dtype=float))
        if self.dependent_noise is None:
            out = np.zeros((len(t), self.dim, self.dim))
        else:
            out = np.asarray(self.dependent_noise(t), dtype=float)
        return out[0] if scalar else out

    # ---------------------------------------------------------------- augmentation
    def with_parameters(self, names, units, variances) -> "AugmentedModel":
        """This model with random-walk parameters appended (sensor biases, R4 ``with_bias``).

        ``variances`` are their per-step disturbance variances (V_w gets them on the diagonal).
        """
        names, units = tuple(names), tuple(units)
        variances = np.atleast_1d(np.asarray(variances, dtype=float))
        extra = len(names)
        if len(units) != extra or len(variances) != extra:
            raise ValueError(f"{self.name}: one unit and one variance per appended parameter")
        n = self.dim
        p = self.n_parameters
        V_w = np.zeros((p + extra, p + extra))
        V_w[:p, :p] = self.V_w
        V_w[p:, p:] = np.diag(variances)

        def pad(matrix_fn, identity):
            def padded(t):
                inner = matrix_fn(t)
                out = np.zeros(inner.shape[:-2] + (n + extra, n + extra))
                out[..., :n, :n] = inner
                if identity:
                    out[..., n:, n:] = np.eye(extra)
                return out
            return padded

        changes = dict(components=self.components + names, units=self.units + units,
                       parameters=self.parameters + names, V_w=V_w, name=self.name)
        if self.transition is not None:
            inner_phi = self.transition
            changes["transition"] = lambda x, t: np.concatenate([inner_phi(x[:, :n], t), x[:, n:]], axis=1)
        if self.transition_matrix is not None:
            changes["transition_matrix"] = pad(self.transition_matrix, identity=True)
        if self.drift is not None:
            inner_f = self.drift
            changes["drift"] = lambda x: np.concatenate([inner_f(x[:, :n]), np.zeros_like(x[:, n:])], axis=1)
        if self.jacobian is not None:
            inner_j = self.jacobian

            def jacobian(x, t):
                inner = inner_j(x[:, :n], t)
                out = np.zeros((len(x), n + extra, n + extra))
                out[:, :n, :n] = inner
                out[:, n:, n:] = np.eye(extra)
                return out
            changes["jacobian"] = jacobian
        if self.dependent_noise is not None:
            changes["dependent_noise"] = pad(self.dependent_noise, identity=False)
        return replace(self, **changes)

    def with_dependent_noise(self, dependent_noise) -> "AugmentedModel":
        """The same model with Q_dep(T) (T ``[K]`` -> ``[K, n, n]``)."""
        return replace(self, dependent_noise=dependent_noise)

    def __repr__(self) -> str:
        return (f"AugmentedModel({self.name!r}, components={self.components}, "
                f"parameters={self.parameters})")


def white_acceleration_noise(q_a: float, position_index=(0, 1), velocity_index=(2, 3), dim: int = 5):
    """Q_dep(T) of white acceleration of PSD ``q_a`` (m^2/s^3) per axis (R14):
    ``q_a [[T^3/3, T^2/2], [T^2/2, T]]`` on each (position, velocity) pair."""
    if not (math.isfinite(q_a) and q_a >= 0):
        raise ValueError(f"white acceleration PSD must be finite and >= 0, got {q_a}")

    def dependent_noise(t: np.ndarray) -> np.ndarray:
        Q = np.zeros((len(t), dim, dim))
        for p, v in zip(position_index, velocity_index):
            Q[:, p, p] = q_a * t**3 / 3.0
            Q[:, p, v] = Q[:, v, p] = q_a * t * t / 2.0
            Q[:, v, v] = q_a * t
        return Q
    return dependent_noise


# -------------------------------------------------------------------- R2: ct-omega
CT_COMPONENTS = ("x", "y", "vx", "vy", "omega")
CT_UNITS = ("m", "m", "m/s", "m/s", "rad/s")


def ct_coefficients(omega: np.ndarray, T: np.ndarray):
    """``(s, c, s', c', sin wT, cos wT)`` of R2; series for ``|wT| < 1e-3``.

    ``s = sin(wT)/w``, ``c = (1 - cos wT)/w`` and their omega-derivatives ``s'``, ``c'``.
    """
    w = np.asarray(omega, dtype=float)
    t = np.asarray(T, dtype=float)
    wt = w * t
    sin, cos = np.sin(wt), np.cos(wt)
    series = np.abs(wt) < CT_SERIES_BELOW
    # the closed forms are evaluated on a safe omega so that the unused branch does not divide by 0
    ws = np.where(series, 1.0, w)
    one_minus_cos = 2.0 * np.sin(0.5 * wt) ** 2  # no cancellation near wT = 0
    s = np.where(series, t * (1.0 - wt**2 / 6.0 + wt**4 / 120.0), sin / ws)
    c = np.where(series, t * (wt / 2.0 - wt**3 / 24.0), one_minus_cos / ws)
    ds = np.where(series, -w * t**3 / 3.0 + w**3 * t**5 / 30.0, (wt * cos - sin) / ws**2)
    dc = np.where(series, t**2 / 2.0 - w**2 * t**4 / 8.0, (wt * sin - one_minus_cos) / ws**2)
    return s, c, ds, dc, sin, cos


def ct_omega_transition(x: np.ndarray, T: np.ndarray) -> np.ndarray:
    """phi of R2 for states ``[K, 5]`` = (x, y, vx, vy, omega)."""
    px, py, vx, vy, w = x.T
    s, c, _, _, sin, cos = ct_coefficients(w, T)
    return np.stack([px + s * vx - c * vy, py + c * vx + s * vy,
                     cos * vx - sin * vy, sin * vx + cos * vy, w], axis=1)


def ct_omega_jacobian(x: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Analytic F of R2 ``[K, 5, 5]``; its omega column is G."""
    _, _, vx, vy, w = x.T
    t = np.asarray(T, dtype=float)
    s, c, ds, dc, sin, cos = ct_coefficients(w, t)
    F = np.zeros((len(x), 5, 5))
    F[:, 0, 0] = F[:, 1, 1] = F[:, 4, 4] = 1.0
    F[:, 0, 2], F[:, 0, 3] = s, -c
    F[:, 1, 2], F[:, 1, 3] = c, s
    F[:, 2, 2], F[:, 2, 3] = cos, -sin
    F[:, 3, 2], F[:, 3, 3] = sin, cos
    F[:, 0, 4] = ds * vx - dc * vy
    F[:, 1, 4] = dc * vx + ds * vy
    F[:, 2, 4] = -t * (sin * vx + cos * vy)
    F[:, 3, 4] = t * (cos * vx - sin * vy)
    return F


def ct_omega_drift(x: np.ndarray) -> np.ndarray:
    """Drift of R2 as eq. (1): ``f = (vx, vy, -omega vy, omega vx, 0)`` (TV7 drift route)."""
    _, _, vx, vy, w = x.T
    return np.stack([vx, vy, -w * vy, w * vx, np.zeros_like(w)], axis=1)


def ct_omega(sigma_omega: float = 1e-4, q_accel: float = 0.0, route: str = "exact") -> AugmentedModel:
    """``ct-omega`` (R2): x = (x, y, vx, vy, omega), parameter omega (rad/s, > 0 counter-clockwise).

    ``sigma_omega`` is the per-step std of the omega random walk (V_w = sigma_omega^2);
    ``q_accel`` > 0 adds white-acceleration Q_dep (R14); ``route="drift"`` integrates the drift by
    RK4 with F by central differences (R1 b) instead of the exact phi and analytic F.
    """
    if not (math.isfinite(sigma_omega) and sigma_omega >= 0):
        raise ValueError(f"ct-omega: sigma_omega must be finite and >= 0, got {sigma_omega}")
    noise = white_acceleration_noise(q_accel) if q_accel > 0 else None
    common = dict(name="ct-omega", components=CT_COMPONENTS, units=CT_UNITS, parameters=("omega",),
                  V_w=np.array([[sigma_omega**2]]), dependent_noise=noise)
    if route == "exact":
        return AugmentedModel(transition=ct_omega_transition, jacobian=ct_omega_jacobian, **common)
    if route == "drift":
        return AugmentedModel(drift=ct_omega_drift, **common)
    raise ValueError(f"ct-omega: route must be 'exact' or 'drift', got {route!r}")


# -------------------------------------------------------------------- R3: ca-accel
CA_COMPONENTS = ("x", "y", "vx", "vy", "ax", "ay")
CA_UNITS = ("m", "m", "m/s", "m/s", "m/s^2", "m/s^2")


def ca_accel_matrix(T: np.ndarray) -> np.ndarray:
    """F of R3 ``[K, 6, 6]``: p' = p + vT + aT^2/2, v' = v + aT, a' = a."""
    t = np.asarray(T, dtype=float)
    F = np.broadcast_to(np.eye(6), t.shape + (6, 6)).copy()
    for axis in range(2):
        F[..., axis, 2 + axis] = t
        F[..., axis, 4 + axis] = t * t / 2.0
        F[..., 2 + axis, 4 + axis] = t
    return F


def ca_accel(sigma_accel: float = 0.1, q_accel: float = 0.0) -> AugmentedModel:
    """``ca-accel`` (R3): x = (x, y, vx, vy, ax, ay), parameters (ax, ay) in m/s^2.

    Linear (phi = F x), so G = [T^2/2 I; T I; I].  ``sigma_accel`` is the per-step std of each
    acceleration random walk (V_w = sigma_accel^2 I); ``q_accel`` > 0 adds white-acceleration Q_dep.
    """
    if not (math.isfinite(sigma_accel) and sigma_accel >= 0):
        raise ValueError(f"ca-accel: sigma_accel must be finite and >= 0, got {sigma_accel}")
    noise = white_acceleration_noise(q_accel, dim=6) if q_accel > 0 else None
    return AugmentedModel(name="ca-accel", components=CA_COMPONENTS, units=CA_UNITS,
                          parameters=("ax", "ay"), V_w=sigma_accel**2 * np.eye(2),
                          transition_matrix=ca_accel_matrix, dependent_noise=noise)


def linear_model(name: str, F, components, units, parameters, V_w) -> AugmentedModel:
    """A linear model with a fixed transition matrix F (n x n, the same for every T), phi(x) = F x.

    For models given by their matrix, such as the paper's 6-state example (section 3.5, TV1-TV3).
    """
    matrix = np.array(F, dtype=float)
    n = len(tuple(components))
    if matrix.shape != (n, n):
        raise ValueError(f"{name}: F must be {n} x {n}, got shape {matrix.shape}")
    return AugmentedModel(name=name, components=tuple(components), units=tuple(units),
                          parameters=tuple(parameters), V_w=V_w,
                          transition_matrix=lambda t: np.broadcast_to(matrix, np.shape(t) + (n, n)).copy())


AUGMENTED_MODELS = {"ct-omega": ct_omega, "ca-accel": ca_accel}

"""Coordinated-turn model CT(omega) on the horizontal plane, CV on the vertical (spec 004 §3.3 B, R1).

Horizontal transition (s = sin wT, c = cos wT, w = omega):
``x' = x + (s/w) vx - ((1-c)/w) vy``, ``vx' = c vx - s vy``,
``y' = y + ((1-c)/w) vx + (s/w) vy``, ``vy' = s vx + c vy``;
for ``|wT| < 1e-6`` the series ``s/w ~ T``, ``(1-c)/w ~ w T^2/2`` (omega = 0 is CV).
``(1-c)/w`` is evaluated as ``2 sin^2(wT/2)/w`` (no cancellation).  The z axis (``ndim=3``) is
constant velocity.  Process noise: DWNA per axis, ``Q_axis = sigma_w^2 g g^T``,
``g = [T^2/2, T]`` (``sigma_w_vertical`` on z, default sigma_w); or, with
``noise="continuous"``, white acceleration of PSD ``q = sigma_w^2`` (m^2/s^3) on the turning
velocity, discretised exactly (order-2 horizontal block, w = omega):
``Q_pp = 2q (wT - sin wT)/w^3``, ``Q_pv = q (1 - cos wT)/w^2`` (own axis),
``Q_x,vy = q (wT - sin wT)/w^2 = -Q_vx,y``, ``Q_vv = q T``, ``Q_xy = Q_vx,vy = 0``
(Van Loan of the CT generator; series below ``|wT| < 0.1``), and CV's continuous Q on z.
The continuous form is the tracker's: its variance grows with the step as it should for
uneven revisit intervals, where DWNA's ``T^2`` velocity variance does not.

Two layouts (axis-major, spec 004 §2):

* ``order=2``: ``[x, vx, y, vy(, z, vz)]`` — the layout of the tracker's CV model, for an IMM
  of CV and CT;
* ``order=3``: the m = 3 embedding ``[x, vx, ax, y, vy, ay(, z, vz, az)]`` used by the
  multiple-model filters of spec 004.  The old accelerations do not enter the prediction.
  ``ct_acceleration="zero"`` (default): the acceleration rows of F and Q are zero;
  ``"centripetal"``: ``a' = Omega v'`` with ``Omega = w [[0, -1], [1, 0]]`` (horizontal), i.e.
  F and Q are those of order 2 mapped through ``J`` (``a = Omega v``): ``F3 = J F2 S``,
  ``Q3 = J Q2 J^T`` with ``S`` dropping the old accelerations.  z acceleration is zero.

The order-3 F is singular (zero or dependent acceleration rows), so a filter cannot invert it
to extrapolate backwards (``KalmanFilter`` with ``dt < 0`` uses its Moore-Penrose inverse: the
order-2 model run back, accelerations kept at zero);
``F(0)`` is the identity only for ``order=2``.

:class:`CoordinatedTurn` has the attributes and methods filters take from
:class:`~skytrack.models.motion.MotionModel` (``dim, ndim, order, position_index,
velocity_index, identical_axes (False), is_linear, F_batch, Q_batch, F, Q, f, scaled,
embed_position``) but no per-axis ``axes``: the horizontal axes are coupled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from skytrack.models.motion import _as_steps

#: |omega T| below which the small-angle series is used (spec 004 §3.3 B)
SMALL_TURN = 1e-6
CT_ACCELERATION = ("zero", "centripetal")
CT_NOISE = ("dwna", "continuous")
#: |omega T| below which the continuous-noise Q uses its series (4 terms: truncation < 1e-16
#: relative there, while the closed form loses ~1e-16/(wT)^3 to cancellation)
SMALL_TURN_Q = 0.1


def turn_coefficients(omega: float, dt) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(s/w, (1-c)/w, c, s)`` of CT(omega) for steps ``dt`` (small-angle series for |wT| < 1e-6)."""
    t = np.asarray(dt, dtype=float)
    w = omega * t
    small = np.abs(w) < SMALL_TURN
    s = np.sin(w)
    c = np.cos(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_over = np.where(small, t, s / omega)
        one_minus_c_over = np.where(small, omega * t * t / 2.0, 2.0 * np.sin(0.5 * w) ** 2 / omega)
    return s_over, one_minus_c_over, c, s


@dataclass(frozen=True)
class CoordinatedTurn:
    """CT(omega) with DWNA noise; ``ndim`` 2 (horizontal) or 3 (CV on z); ``order`` 2 or 3 (embedding).

    ``omega`` is the turn rate (rad/s, positive counter-clockwise seen from above), ``sigma_w``
    the DWNA acceleration standard deviation (m/s^2) of x and y, ``sigma_w_vertical`` that of z
    (None: sigma_w).  ``ct_acceleration`` applies to ``order=3`` only.
    """

    omega: float
    sigma_w: float
    ndim: int = 3
    order: int = 2
    ct_acceleration: str = "zero"
    sigma_w_vertical: float | None = None
    noise: str = "dwna"

    def __post_init__(self):
        if not math.isfinite(self.omega):
            raise ValueError(f"coordinated turn: omega must be finite, got {self.omega}")
        for name in ("sigma_w", "sigma_w_vertical"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"coordinated turn: {name} must be finite and >= 0, got {value}")
        if self.ndim not in (2, 3):
            raise ValueError(f"coordinated turn: ndim must be 2 or 3, got {self.ndim!r}")
        if self.order not in (2, 3):
            raise ValueError(f"coordinated turn: order must be 2 or 3 (m = 3 embedding), got {self.order!r}")
        if self.noise not in CT_NOISE:
            raise ValueError(f"coordinated turn: noise must be one of {CT_NOISE}, got {self.noise!r}")
        if self.ct_acceleration not in CT_ACCELERATION:
            raise ValueError(f"coordinated turn: ct_acceleration must be one of {CT_ACCELERATION}, "
                             f"got {self.ct_acceleration!r}")

    # ------------------------------------------------------------------ MotionModel protocol
    @property
    def dim(self) -> int:
        return self.ndim * self.order

    @property
    def identical_axes(self) -> bool:
        return False

    @property
    def is_linear(self) -> bool:
        return True

    @property
    def position_index(self) -> np.ndarray:
        return np.arange(self.ndim) * self.order

    @property
    def velocity_index(self) -> np.ndarray:
        return np.arange(self.ndim) * self.order + 1

    def F(self, dt: float) -> np.ndarray:
        return self.F_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def Q(self, dt: float) -> np.ndarray:
        return self.Q_batch(_as_steps(dt, allow_zero=False).reshape(1))[0]

    def f(self, x: np.ndarray, dt) -> np.ndarray:
        """Deterministic transition ``F(dt) x`` of states ``[K, n]``."""
        return np.einsum("kij,kj->ki", self.F_batch(np.broadcast_to(dt, (len(x),))), x)

    def scaled(self, factor: float) -> "CoordinatedTurn":
        """The same model with its process noise Q multiplied by ``factor``."""
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"process-noise factor must be finite and > 0, got {factor}")
        root = math.sqrt(factor)
        vertical = None if self.sigma_w_vertical is None else self.sigma_w_vertical * root
        return replace(self, sigma_w=self.sigma_w * root, sigma_w_vertical=vertical)

    def embedded(self, order: int = 3) -> "CoordinatedTurn":
        """The same turn in the layout of ``order`` states per axis (2 or 3)."""
        return replace(self, order=order)

    def embed_position(self, positions: np.ndarray) -> np.ndarray:
        """State vectors ``[K, dim]`` with the given positions ``[K, ndim]`` and zero derivatives."""
        x = np.zeros(positions.shape[:-1] + (self.dim,))
        x[..., self.position_index] = positions
        return x

    # ------------------------------------------------------------------ matrices
    def _f2(self, t: np.ndarray) -> np.ndarray:
        s_over, one_minus_c_over, c, s = turn_coefficients(self.omega, t)
        F = np.zeros(t.shape + (2 * self.ndim, 2 * self.ndim))
        F[..., 0, 0] = F[..., 2, 2] = 1.0
        F[..., 0, 1] = s_over
        F[..., 0, 3] = -one_minus_c_over
        F[..., 1, 1] = c
        F[..., 1, 3] = -s
        F[..., 2, 1] = one_minus_c_over
        F[..., 2, 3] = s_over
        F[..., 3, 1] = s
        F[..., 3, 3] = c
        if self.ndim == 3:
            F[..., 4, 4] = F[..., 5, 5] = 1.0
            F[..., 4, 5] = t
        return F

    def _q2(self, t: np.ndarray) -> np.ndarray:
        if self.noise == "continuous":
            return self._q2_continuous(t)
        Q = np.zeros(t.shape + (2 * self.ndim, 2 * self.ndim))
        vertical = self.sigma_w if self.sigma_w_vertical is None else self.sigma_w_vertical
        for axis in range(self.ndim):
            sigma = vertical if axis == 2 else self.sigma_w
            # sigma g first, so that Q is exactly symmetric
            g = (sigma * (t * t / 2.0), sigma * t)
            for i in range(2):
                for j in range(2):
                    Q[..., 2 * axis + i, 2 * axis + j] = g[i] * g[j]
        return Q

    def _q2_continuous(self, t: np.ndarray) -> np.ndarray:
        q, w = self.sigma_w**2, self.omega
        wt = w * t
        small = np.abs(wt) < SMALL_TURN_Q
        with np.errstate(divide="ignore", invalid="ignore"):
            # (wT - sin wT)/w^3 and (1 - cos wT)/w^2, with their series for small wT
            x2 = wt * wt
            a = np.where(small, t**3 * (1 / 6 - x2 * (1 / 120 - x2 * (1 / 5040 - x2 / 362880))),
                         (wt - np.sin(wt)) / w**3)
            b = np.where(small, t * t * (1 / 2 - x2 * (1 / 24 - x2 * (1 / 720 - x2 / 40320))),
                         2.0 * np.sin(0.5 * wt) ** 2 / (w * w))
        Q = np.zeros(t.shape + (2 * self.ndim, 2 * self.ndim))
        Q[..., 0, 0] = Q[..., 2, 2] = 2.0 * q * a
        Q[..., 0, 1] = Q[..., 1, 0] = Q[..., 2, 3] = Q[..., 3, 2] = q * b
        Q[..., 0, 3] = Q[..., 3, 0] = q * w * a
        Q[..., 1, 2] = Q[..., 2, 1] = -q * w * a
        Q[..., 1, 1] = Q[..., 3, 3] = q * t
        if self.ndim == 3:
            qz = q if self.sigma_w_vertical is None else self.sigma_w_vertical**2
            Q[..., 4, 4] = qz * t**3 / 3.0
            Q[..., 4, 5] = Q[..., 5, 4] = qz * t * t / 2.0
            Q[..., 5, 5] = qz * t
        return Q

    def _embed(self, M2: np.ndarray, columns: bool) -> np.ndarray:
        """Order-2 matrices -> order 3: rows through ``J`` and columns through ``J^T`` (Q) or ``S`` (F)."""
        keep = np.array([3 * a + r for a in range(self.ndim) for r in range(2)])
        M3 = np.zeros(M2.shape[:-2] + (3 * self.ndim, 3 * self.ndim))
        M3[..., keep[:, None], keep[None, :]] = M2
        if self.ct_acceleration == "centripetal":
            w = self.omega
            # a_x' = -w v_y', a_y' = w v_x' (x: indices 0..2, y: 3..5)
            M3[..., 2, :] = -w * M3[..., 4, :]
            M3[..., 5, :] = w * M3[..., 1, :]
            if columns:
                M3[..., :, 2] = -w * M3[..., :, 4]
                M3[..., :, 5] = w * M3[..., :, 1]
        return M3

    def F_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        F2 = self._f2(t)
        return F2 if self.order == 2 else self._embed(F2, columns=False)

    def Q_batch(self, dt) -> np.ndarray:
        t = _as_steps(dt, allow_zero=True)
        Q2 = self._q2(t)
        return Q2 if self.order == 2 else self._embed(Q2, columns=True)

    def __repr__(self) -> str:
        return (f"CoordinatedTurn(omega={self.omega!r}, sigma_w={self.sigma_w!r}, ndim={self.ndim}, "
                f"order={self.order}, ct_acceleration={self.ct_acceleration!r}, "
                f"sigma_w_vertical={self.sigma_w_vertical!r}, noise={self.noise!r})")


def coordinated_turn(ndim: int, omega: float, sigma_w: float, order: int = 2,
                     ct_acceleration: str = "zero", sigma_w_vertical: float | None = None,
                     noise: str = "dwna") -> CoordinatedTurn:
    """CT(omega) in ``ndim`` (2 or 3) dimensions, ``order`` 2 or 3 states per axis."""
    return CoordinatedTurn(omega, sigma_w, ndim, order, ct_acceleration, sigma_w_vertical, noise)

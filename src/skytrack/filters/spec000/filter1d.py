"""The paper's 1-D Singer filter for one track (spec 000, R3, R4, R6, R7, R10, R13, R16).

What lives here: :class:`SingerFilter1D` and its per-scan output :class:`StepResult`.  It is
a :class:`~skytrack.filters.spec000.bank1d.SingerFilterBank1D` of size one plus the
switching-coefficient interface of R10 (per-step :class:`SingerParams`, a non-anticipative
``coefficient_policy`` and the recorded history).  One scan is Theorem 2 (5) then Theorem 1
(3)-(4) ((F1)-(F10) for the paper model); a missed scan is the prediction alone (S1).
:meth:`SingerFilter1D.extrapolate` is Theorem 2 (R6) and
:meth:`SingerFilter1D.predicted_innovation` the gate statistics (nu, S, d^2) of R7.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from skytrack.filters.ekf import innovation, mahalanobis
from skytrack.filters.spec000.bank1d import SingerFilterBank1D
from skytrack.filters.spec000.params import SingerHistory, SingerParams
from skytrack.filters.spec000.validation import _check_dt
from skytrack.models.motion import SingerAxisModel


@dataclass
class StepResult:
    """Outputs of one scan (R3): innovation ``nu[k]``, ``S[k, k]``, gain ``K[3, k]``, ``d2``.

    On a missed scan there is no innovation: nu and d2 are NaN and K is zero (Gamma_D = 0,
    S1); S is the predicted innovation covariance that sizes the gate.
    """

    nu: np.ndarray
    S: np.ndarray
    K: np.ndarray
    d2: float
    detected: bool
    m: np.ndarray
    P: np.ndarray


class SingerFilter1D:
    """The paper's 1-D Singer filter with missed detections (spec 000: R3, R4, R6, R10, R13, R16).

    ``measurement="pos"``: H = [1 0 0], R = sigma^2; ``"posvel"``: H = [[1,0,0],[0,1,0]],
    R = diag(sigma^2, sigma_v^2).  The discretisation is the model's (``"paper"`` K6 or
    ``"exact"`` X1-X2); :meth:`from_parameters` builds one with the paper's default.
    ``coefficient_policy(history) -> SingerParams`` (R10) is called before each
    prediction that is not given explicit ``params``.
    """

    def __init__(
        self,
        model: SingerAxisModel,
        sigma: float,
        measurement: str = "pos",
        sigma_v: float | None = None,
        *,
        update_form: str = "joseph",
        coefficient_policy: Callable[[SingerHistory], SingerParams] | None = None,
        m0=None,
        P0=None,
    ):
        if np.ndim(sigma) != 0:
            raise ValueError("SingerFilter1D takes a scalar sigma; use SingerFilterBank1D for several tracks")
        self._bank = SingerFilterBank1D(model, sigma, measurement, sigma_v, n_tracks=1, update_form=update_form)
        if coefficient_policy is not None and not callable(coefficient_policy):
            raise TypeError("coefficient_policy must be callable: history -> SingerParams")
        self.coefficient_policy = coefficient_policy
        self.history = SingerHistory()
        if (m0 is None) != (P0 is None):
            raise ValueError("give both m0 and P0, or neither")
        if m0 is not None:
            self.set_state(m0, P0)

    @classmethod
    def from_parameters(
        cls, tau: float, sigma_a: float, sigma: float, measurement: str = "pos", sigma_v: float | None = None,
        discretization: str = "paper", **kwargs,
    ) -> "SingerFilter1D":
        """Build the model too; the 1-D paper filter defaults to the ``"paper"`` discretisation (R2)."""
        return cls(SingerAxisModel(tau, sigma_a, discretization), sigma, measurement, sigma_v, **kwargs)

    # ---- attributes -------------------------------------------------------
    model = property(lambda self: self._bank.model)
    measurement = property(lambda self: self._bank.measurement)
    update_form = property(lambda self: self._bank.update_form)
    sigma = property(lambda self: float(self._bank.sigma[0]))
    sigma_v = property(lambda self: self._bank.sigma_v)

    @property
    def m(self) -> np.ndarray:
        return self._bank.m[0].copy()

    @property
    def P(self) -> np.ndarray:
        return self._bank.P[0].copy()

    @property
    def H(self) -> np.ndarray:
        return np.eye(3)[list(self._bank.index)]

    @property
    def R(self) -> np.ndarray:
        return self._bank.R[0].copy()

    @property
    def params_used(self) -> list[SingerParams]:
        """The coefficients used at every step so far (R10)."""
        return list(self.history.params)

    # ---- initialisation (R13) ---------------------------------------------
    def set_state(self, m, P) -> None:
        self._bank.set_state(np.asarray(m, dtype=float).reshape(3), np.asarray(P, dtype=float).reshape(3, 3))

    def initialize(self, z0, init: str = "paper", *, sigma_v0: float | None = None, dt: float | None = None) -> None:
        """Start from the first report ``z0`` (scalar, or (z0, Vz0) for posvel).

        ``init="paper"`` is (A0): P = diag(sigma^2, sigma_v0^2, sigma_a^2); ``init="steady"``
        uses P+ of :func:`steady_state` for scan period ``dt``.
        """
        z0 = np.asarray(z0, dtype=float).reshape(1, -1)
        if init == "paper":
            self._bank.initialize_paper(z0, sigma_v0)
        elif init == "steady":
            if dt is None:
                raise ValueError('init="steady" needs the scan period dt')
            self._bank.initialize_steady(z0, dt)
        else:
            raise ValueError(f'init must be "paper" or "steady", got {init!r}')

    # ---- Theorem 2 / Theorem 1 --------------------------------------------
    def extrapolate(self, dt: float, params: SingerParams | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Pure one-step extrapolation (R6, Theorem 2): returns (e-m, e-gamma) without changing the filter."""
        m_pred, P_pred = self._bank.extrapolate(dt, params)
        return m_pred[0], P_pred[0]

    def _params_for_step(self, params: SingerParams | None) -> SingerParams:
        if params is not None:
            if not isinstance(params, SingerParams):
                raise TypeError(f"params must be SingerParams, got {type(params).__name__}")
            return params
        if self.coefficient_policy is not None:
            chosen = self.coefficient_policy(self.history)
            if not isinstance(chosen, SingerParams):
                raise TypeError(f"coefficient_policy must return SingerParams, got {type(chosen).__name__}")
            return chosen
        return SingerParams.of(self.model)

    def predict(self, dt: float, params: SingerParams | None = None) -> SingerParams:
        """Advance the state by Theorem 2 over ``dt``; returns the coefficients used."""
        used = self._params_for_step(params)
        self._bank.predict(dt, used)
        return used

    def innovation_covariance(self) -> np.ndarray:
        """S = H P H^T + R at the current (usually predicted) state."""
        P = self._bank.P[0]
        idx = list(self._bank.index)
        return P[np.ix_(idx, idx)] + self.R

    def predicted_innovation(self, z, dt: float, params: SingerParams | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Gate statistics of a report ``z`` taken ``dt`` after the current state (R7), without updating.

        Returns (nu, S, d2): nu = z - H e-m, S = H e-gamma H^T + R of the extrapolation to the
        report's own timestamp, d2 = nu^T S^-1 nu (Cholesky).
        """
        z = np.atleast_1d(np.asarray(z, dtype=float))
        if z.shape != (self._bank.dim_z,) or not np.all(np.isfinite(z)):
            raise ValueError(f"z must be {self._bank.dim_z} finite value(s) for measurement={self.measurement!r}, got {z!r}")
        m_pred, P_pred = self.extrapolate(dt, params)
        idx = list(self._bank.index)
        nu = innovation(z, m_pred[idx])
        S = P_pred[np.ix_(idx, idx)] + self.R
        return nu, S, float(mahalanobis(nu[None], S[None])[0])

    def step(self, z, detected: bool, dt: float, params: SingerParams | None = None) -> StepResult:
        """One scan: predict over ``dt`` then update if ``detected`` (R3, R4); z is ignored on a miss."""
        if not isinstance(detected, (bool, np.bool_, int, np.integer)) or detected not in (0, 1):
            raise ValueError(f"detected must be True/False (or 1/0), got {detected!r}")
        dt = _check_dt(dt)
        used = self.predict(dt, params)
        z_row = None
        if detected:
            if z is None:
                raise ValueError("a detected scan needs a measurement z")
            z_row = np.asarray(z, dtype=float).reshape(1, -1)
        out = self._bank.update(z_row, np.array([bool(detected)]))
        result = StepResult(
            nu=out.nu[0], S=out.S[0], K=out.K[0], d2=float(out.d2[0]), detected=bool(detected), m=self.m, P=self.P
        )
        self.history.append(dt, used, detected, None if z_row is None else z_row[0].copy(), result.m, result.d2)
        return result

"""N independent 1-D Singer filters advanced together (spec 000, R3, R4, R6, R13).

What lives here: :class:`SingerFilterBank1D` and its step result :class:`BankStepResult`,
the batched form of the paper's 1-D filter used by the accuracy study (E1-E6), the Monte
Carlo consistency check (R14) and the long-run hygiene check (R16).  One step is Theorem 2
(5) followed by Theorem 1 (3)-(4) in Kalman form (F1)-(F10) on detected rows; a missed row is
the prediction alone (S1, R4).  Initialisation is the paper's (A0) or the steady state of R12
(R13).  Public arrays are batch-first; the state is kept batch-last
(:mod:`skytrack.filters.spec000.kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skytrack.filters.spec000.kernels import (
    _axis_FQ,
    _mahalanobis_from_cholesky,
    _measurement_noise_bl,
    _predict_bl,
    _update_cov_bl,
)
from skytrack.filters.spec000.params import SingerParams
from skytrack.filters.spec000.steady_state import steady_state
from skytrack.filters.spec000.validation import (
    _check_covariance,
    _check_dt,
    _check_form,
    _check_measurement,
    _check_sigma,
)
from skytrack.models.motion import SingerAxisModel


@dataclass
class BankStepResult:
    """Innovation statistics of one bank step (batch-first). Missed rows: nu, d2 NaN, K zero."""

    nu: np.ndarray  # [N, k]
    S: np.ndarray  # [N, k, k]
    K: np.ndarray  # [N, 3, k]
    d2: np.ndarray  # [N]
    detected: np.ndarray  # [N]


class SingerFilterBank1D:
    """N independent 1-D Singer filters with a shared model and measurement variant (R3, R4, R6).

    ``sigma`` is the position-measurement st. dev. (scalar or one per track), ``sigma_v`` the
    velocity one for ``measurement="posvel"``.  The state must be set with :meth:`set_state`,
    :meth:`initialize_paper` or :meth:`initialize_steady` before stepping.
    """

    def __init__(
        self,
        model: SingerAxisModel,
        sigma,
        measurement: str = "pos",
        sigma_v: float | None = None,
        *,
        n_tracks: int | None = None,
        update_form: str = "joseph",
    ):
        if not isinstance(model, SingerAxisModel):
            raise TypeError(f"model must be a SingerAxisModel, got {type(model).__name__}")
        self.model = model
        self.measurement = measurement
        self.index = _check_measurement(measurement)
        self.update_form = _check_form(update_form)
        self.sigma = _check_sigma("sigma", sigma)
        if len(self.index) == 2:
            self.sigma_v = float(_check_sigma("sigma_v", sigma_v)[0])
        else:
            if sigma_v is not None:
                _check_sigma("sigma_v", sigma_v)
            self.sigma_v = None if sigma_v is None else float(sigma_v)
        size = self.sigma.size if n_tracks is None else int(n_tracks)
        if size < 1 or (self.sigma.size not in (1, size)):
            raise ValueError(f"sigma has {self.sigma.size} values for {size} tracks")
        self.n_tracks = size
        self._R = _measurement_noise_bl(self.index, self.sigma, self.sigma_v)
        self._m: np.ndarray | None = None
        self._P: np.ndarray | None = None

    # ---- state -----------------------------------------------------------
    @property
    def dim_z(self) -> int:
        return len(self.index)

    @property
    def m(self) -> np.ndarray:
        self._require_state()
        return self._m.T

    @property
    def P(self) -> np.ndarray:
        self._require_state()
        return self._P.transpose(2, 0, 1)

    @property
    def R(self) -> np.ndarray:
        """Measurement noise covariance [N, k, k]."""
        return np.broadcast_to(self._R, (self.dim_z, self.dim_z, self.n_tracks)).transpose(2, 0, 1)

    def _require_state(self) -> None:
        if self._m is None:
            raise ValueError("filter state is not initialised; call set_state or an initialize_* method")

    def set_state(self, m, P) -> None:
        """Set means ``m[N, 3]`` (or [3]) and covariances ``P[N, 3, 3]`` (or [3, 3])."""
        m = np.asarray(m, dtype=float)
        P = np.asarray(P, dtype=float)
        if m.shape[-1:] != (3,) or P.shape[-2:] != (3, 3):
            raise ValueError(f"state must be m[..., 3] and P[..., 3, 3], got {m.shape} and {P.shape}")
        if not np.all(np.isfinite(m)):
            raise ValueError("initial mean contains non-finite values")
        _check_covariance("initial covariance", P)
        self._m = np.broadcast_to(m, (self.n_tracks, 3)).T.copy()
        self._P = np.broadcast_to(P, (self.n_tracks, 3, 3)).transpose(1, 2, 0).copy()

    def _initial_mean(self, z0) -> np.ndarray:
        z0 = self._check_z(z0, np.ones(self.n_tracks, dtype=bool))
        m0 = np.zeros((self.n_tracks, 3))
        m0[:, list(self.index)] = z0
        return m0

    def initialize_paper(self, z0, sigma_v0: float | None = None) -> None:
        """The paper's start (A0, R13): m = (z0, 0, 0) or (z0, Vz0, 0), P = diag(sigma^2, sigma_v0^2, sigma_a^2).

        ``sigma_v0`` defaults to ``sigma_v`` for posvel and must be given for pos.
        """
        if sigma_v0 is None:
            if self.sigma_v is None or len(self.index) == 1:
                raise ValueError("initialize_paper: sigma_v0 (initial velocity st. dev.) must be given for measurement='pos'")
            sigma_v0 = self.sigma_v
        sigma_v0 = float(_check_sigma("sigma_v0", sigma_v0)[0])
        P0 = np.zeros((self.n_tracks, 3, 3))
        P0[:, 0, 0] = np.broadcast_to(self.sigma, (self.n_tracks,)) ** 2
        P0[:, 1, 1] = sigma_v0**2
        P0[:, 2, 2] = self.model.sigma_a**2
        if self.model.sigma_a == 0:
            raise ValueError("initialize_paper needs sigma_a > 0 (it is the prior st. dev. of acceleration)")
        self.set_state(self._initial_mean(z0), P0)

    def initialize_steady(self, z0, dt: float) -> None:
        """``init="steady"`` (R13): m as in the paper start, P = P+ of :func:`steady_state`."""
        m0 = self._initial_mean(z0)
        sig = np.broadcast_to(self.sigma, (self.n_tracks,))
        cache: dict[float, np.ndarray] = {}
        P0 = np.empty((self.n_tracks, 3, 3))
        for i, s in enumerate(sig):
            if s not in cache:
                cache[s] = steady_state(self.model, self.measurement, sigma=s, dt=dt, sigma_v=self.sigma_v, update_form=self.update_form).P_filt
            P0[i] = cache[s]
        self.set_state(m0, P0)

    # ---- Theorem 2 -------------------------------------------------------
    def _FQ(self, dt: float, params: SingerParams | None):
        if params is not None and not isinstance(params, SingerParams):
            raise TypeError(f"params must be SingerParams, got {type(params).__name__}")
        return _axis_FQ(self.model, params, _check_dt(dt))

    def extrapolate(self, dt: float, params: SingerParams | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Pure Theorem 2 (5) (R6): returns (F m, F P F^T + Q) as ([N, 3], [N, 3, 3]); the state is unchanged."""
        self._require_state()
        F, Q = self._FQ(dt, params)
        m_pred, P_pred = _predict_bl(self._m, self._P, F, Q)
        return m_pred.T, P_pred.transpose(2, 0, 1)

    def predict(self, dt: float, params: SingerParams | None = None) -> None:
        """Replace the state by its one-step extrapolation (same code path as :meth:`extrapolate`)."""
        self._require_state()
        F, Q = self._FQ(dt, params)
        self._m, self._P = _predict_bl(self._m, self._P, F, Q)

    # ---- Theorem 1 update --------------------------------------------------
    def _check_z(self, z, detected: np.ndarray) -> np.ndarray:
        """Measurements as [N, k]; a scalar (pos) or a length-k vector is shared when N = 1 or k = 1."""
        k, n = self.dim_z, self.n_tracks
        if z is None:
            if np.any(detected):
                raise ValueError("measurement z is None but a scan is flagged detected")
            return np.zeros((n, k))
        z = np.asarray(z, dtype=float)
        if z.ndim == 0 and k == 1:
            z = np.full((n, 1), float(z))
        elif z.ndim == 1 and k == 1 and z.shape[0] == n:
            z = z[:, None]
        elif z.ndim == 1 and n == 1 and z.shape[0] == k:
            z = z[None, :]
        if z.shape != (n, k):
            raise ValueError(f"z must have shape [{n}, {k}] for measurement={self.measurement!r}, got {z.shape}")
        bad = detected & ~np.all(np.isfinite(z), axis=1)
        if np.any(bad):
            raise ValueError(f"non-finite measurement at detected track(s) {np.flatnonzero(bad)[:10].tolist()}")
        return np.where(detected[:, None], z, 0.0)

    def update(self, z, detected) -> BankStepResult:
        """Measurement update where ``detected`` (bool[N]) is True; pure extrapolation elsewhere (R4).

        z at missed rows is ignored (None/NaN allowed) and cannot influence the state.
        """
        self._require_state()
        detected = np.broadcast_to(np.asarray(detected, dtype=bool), (self.n_tracks,))
        z = self._check_z(z, detected)
        S, L, K, P_upd = _update_cov_bl(self._P, self.index, self._R, self.update_form)
        idx = list(self.index)
        nu = np.where(detected, z.T - self._m[idx], 0.0)
        m_upd = self._m + sum(K[:, a] * nu[a] for a in range(len(idx)))
        self._m = np.where(detected, m_upd, self._m)
        self._P = np.where(detected, P_upd, self._P)
        d2 = _mahalanobis_from_cholesky(nu, L)
        S_bf = S.transpose(2, 0, 1)
        nu_bf = nu.T
        K_bf = K.transpose(2, 0, 1)
        miss = ~detected
        if np.any(miss):
            nu_bf = np.where(miss[:, None], np.nan, nu_bf)
            d2 = np.where(miss, np.nan, d2)
            K_bf = np.where(miss[:, None, None], 0.0, K_bf)
        return BankStepResult(nu=nu_bf, S=S_bf, K=K_bf, d2=d2, detected=detected.copy())

    def step(self, z, detected, dt: float, params: SingerParams | None = None) -> BankStepResult:
        """One scan: Theorem 2 prediction over ``dt`` then update-or-miss (R3, R4)."""
        self.predict(dt, params)
        return self.update(z, detected)

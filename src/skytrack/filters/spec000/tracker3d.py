"""The 3-D polar-radar Singer EKF of one track (spec 000, R8, R9, R10, R13).

What lives here: :class:`SingerTracker3D` and :class:`Innovation3D`.  The state is
[x, vx, ax, y, vy, ay, z, vz, az] with one Singer axis model per ENU axis (R1, R2; F, Q block
diagonal from (K6) or (X1)-(X2)); the prediction is Theorem 2 (5) and the update the EKF form
of Theorem 1 (3)-(4) with the polar measurement functions r, az, el, rdot, altitude z_alt
and Cartesian x, y, z of R8 (shared with :mod:`skytrack.models.measurement`), angles wrapped
and d^2 from a Cholesky solve (R7).  ``use_range_rate`` selects the paper's position-only or
position + velocity variant (R9, (M2)/(M3) in 3-D); a one-plot start converts the plot to ENU
with covariance J_c R J_c^T (R13).  Built on the batched EKF core :mod:`skytrack.filters.ekf`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from skytrack.filters.ekf import innovation, mahalanobis, predict, symmetrize, update
from skytrack.filters.spec000.kernels import _axis_FQ
from skytrack.filters.spec000.params import SingerHistory, SingerParams
from skytrack.filters.spec000.validation import _check_covariance, _check_dt, _check_form, _check_sigma
from skytrack.geo.polar import polar_to_cartesian
from skytrack.models.measurement import POLAR_COMPONENTS, CartesianPositionModel, PolarMeasurementModel
from skytrack.models.motion import SingerAxisModel, block_diag_batch

#: the tracker refuses polar updates closer than this to the radar (R8)
MIN_RANGE_M = 1.0

#: Cartesian position components of a report (common ENU frame), linear (R8)
CARTESIAN_COMPONENTS = ("x", "y", "z")
REPORT_COMPONENTS = POLAR_COMPONENTS + CARTESIAN_COMPONENTS


@dataclass
class Innovation3D:
    """Innovation of one report at the current (predicted) state of a :class:`SingerTracker3D`."""

    components: tuple[str, ...]
    z: np.ndarray
    h: np.ndarray
    nu: np.ndarray
    H: np.ndarray
    R: np.ndarray
    S: np.ndarray
    d2: float
    angular: np.ndarray


class SingerTracker3D:
    """3-D Singer EKF of one track fed by a radar in polar coordinates (spec 000, R8, R9, R10, R13).

    ``models_xyz``: three :class:`SingerAxisModel` (x east, y north, z up; the tracker
    default discretisation is ``"exact"``, R2), state ``[x, vx, ax, y, vy, ay, z, vz, az]``.
    ``sensor``: an object with ``position`` [3] (common frame) and ``rotation`` [3, 3]
    (common -> sensor frame), e.g. :class:`skytrack.geo.Sensor`; None = radar at the origin.
    ``sigmas``: st. dev. per report component (``r`` m, ``az``/``el`` rad, ``rdot`` m/s,
    ``z_alt`` m, ``x``/``y``/``z`` m); missing radar entries are taken from the sensor's
    ``sigma_range_m``, ``sigma_azimuth_deg``, ``sigma_elevation_deg``, ``sigma_range_rate_mps``.
    ``use_range_rate=False`` is the paper's position-only variant (r, az[, el]); True adds
    the Doppler range rate when a report carries it (R9).
    ``assumed_altitude=(z0, sigma_z0)`` is injected as a ``z_alt`` pseudo-measurement into
    reports that have neither elevation, altitude nor a Cartesian position (R8).
    """

    def __init__(
        self,
        models_xyz: Sequence[SingerAxisModel],
        sensor=None,
        *,
        sigmas: Mapping[str, float] | None = None,
        use_range_rate: bool = False,
        assumed_altitude: tuple[float, float] | None = None,
        update_form: str = "joseph",
        coefficient_policy: Callable[[SingerHistory], SingerParams | Sequence[SingerParams]] | None = None,
    ):
        models = tuple(models_xyz)
        if len(models) != 3 or not all(isinstance(m, SingerAxisModel) for m in models):
            raise ValueError("models_xyz must be three SingerAxisModel (x, y, z axes)")
        self.models = models
        self.update_form = _check_form(update_form)
        self.use_range_rate = bool(use_range_rate)
        self.sensor_position = np.zeros(3) if sensor is None else np.asarray(sensor.position, dtype=float)
        self.sensor_rotation = np.eye(3) if sensor is None else np.asarray(sensor.rotation, dtype=float)
        self.sigmas = self._resolve_sigmas(sensor, sigmas or {})
        if assumed_altitude is not None:
            z0, s0 = assumed_altitude
            if not math.isfinite(float(z0)):
                raise ValueError(f"assumed_altitude z0 must be finite, got {z0!r}")
            _check_sigma("assumed_altitude sigma_z0", s0)
            assumed_altitude = (float(z0), float(s0))
        self.assumed_altitude = assumed_altitude
        if coefficient_policy is not None and not callable(coefficient_policy):
            raise TypeError("coefficient_policy must be callable: history -> SingerParams or three of them")
        self.coefficient_policy = coefficient_policy
        self.history = SingerHistory()
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None

    @staticmethod
    def _resolve_sigmas(sensor, given: Mapping[str, float]) -> dict[str, float]:
        unknown = set(given) - set(REPORT_COMPONENTS)
        if unknown:
            raise ValueError(f"unknown sigma components {sorted(unknown)}; known: {REPORT_COMPONENTS}")
        out: dict[str, float] = {}
        if sensor is not None:
            from_sensor = {
                "r": getattr(sensor, "sigma_range_m", None),
                "az": None if getattr(sensor, "sigma_azimuth_deg", None) is None else math.radians(sensor.sigma_azimuth_deg),
                "el": None if getattr(sensor, "sigma_elevation_deg", None) is None else math.radians(sensor.sigma_elevation_deg),
                "rdot": getattr(sensor, "sigma_range_rate_mps", None),
            }
            out.update({k: float(v) for k, v in from_sensor.items() if v is not None})
        out.update({k: float(v) for k, v in given.items()})
        for name, value in out.items():
            _check_sigma(f"sigma of component {name!r}", value)
        return out

    # ---- model ------------------------------------------------------------
    def _axis_params(self, params) -> tuple[SingerParams, SingerParams, SingerParams]:
        if params is None:
            return tuple(SingerParams.of(m) for m in self.models)
        if isinstance(params, SingerParams):
            return (params, params, params)
        params = tuple(params)
        if len(params) != 3 or not all(isinstance(p, SingerParams) for p in params):
            raise TypeError("params must be SingerParams or a sequence of three (x, y, z)")
        return params

    def transition(self, dt: float, params=None) -> tuple[np.ndarray, np.ndarray]:
        """Block-diagonal F(dt), Q(dt) of the three axes (R1, R2)."""
        dt = _check_dt(dt)
        blocks = [_axis_FQ(model, p, dt) for model, p in zip(self.models, self._axis_params(params))]
        F = block_diag_batch([b[0][None] for b in blocks])[0]
        Q = block_diag_batch([b[1][None] for b in blocks])[0]
        return F, Q

    # ---- state ------------------------------------------------------------
    def _require_state(self) -> None:
        if self.x is None:
            raise ValueError("tracker state is not initialised; call set_state or initialize_from_report")

    def set_state(self, x, P) -> None:
        x = np.asarray(x, dtype=float).reshape(9)
        P = np.asarray(P, dtype=float).reshape(9, 9)
        if not np.all(np.isfinite(x)):
            raise ValueError("initial state contains non-finite values")
        _check_covariance("initial covariance", P)
        self.x, self.P = x.copy(), P.copy()

    def initialize_from_report(self, report: Mapping[str, float], sigma_v0: float) -> None:
        """One-plot start (R13): position from the plot with covariance J_c R J_c^T,
        velocity 0 with sigma_v0^2 and acceleration 0 with sigma_a^2 per axis.

        A polar plot needs r and az plus el, an altitude ``z_alt`` or ``assumed_altitude``
        (the altitude is converted with the sensor's local vertical); a Cartesian plot
        (x, y, z) is taken as it is.
        """
        sigma_v0 = float(_check_sigma("sigma_v0", sigma_v0)[0])
        values = self._report_values(report)
        if all(c in values for c in CARTESIAN_COMPONENTS):
            position = np.array([values[c] for c in CARTESIAN_COMPONENTS])
            cov = np.diag([self._sigma(c) ** 2 for c in CARTESIAN_COMPONENTS])
        else:
            position, cov = self._polar_plot_to_enu(values)
        x = np.zeros(9)
        P = np.zeros((9, 9))
        pos = np.array([0, 3, 6])
        x[pos] = position
        P[np.ix_(pos, pos)] = cov
        P[pos + 1, pos + 1] = sigma_v0**2
        P[pos + 2, pos + 2] = [m.sigma_a**2 for m in self.models]
        self.set_state(x, P)

    def _polar_plot_to_enu(self, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        if "r" not in values or "az" not in values:
            raise ValueError("initialising from a polar plot needs both r and az")
        r, az = values["r"], values["az"]
        if r < MIN_RANGE_M:
            raise ValueError(f"range r = {r} m is below {MIN_RANGE_M} m; plot refused")
        var_r, var_az = self._sigma("r") ** 2, self._sigma("az") ** 2
        if "el" in values:
            el = values["el"]
            # the third measured parameter is el itself: d(el)/d(third) = 1
            var_third, d_el_dr, d_el_dthird = self._sigma("el") ** 2, 0.0, 1.0
        else:
            if "z_alt" in values:
                z_alt, var_z = values["z_alt"], self._sigma("z_alt") ** 2
            elif self.assumed_altitude is not None:
                z_alt, var_z = self.assumed_altitude[0], self.assumed_altitude[1] ** 2
            else:
                raise ValueError("polar plot without el needs z_alt or the tracker's assumed_altitude")
            height = z_alt - self.sensor_position[2]
            if abs(height) >= r:
                raise ValueError(f"altitude difference {height} m is not below the slant range {r} m")
            el = math.asin(height / r)
            cos_el = math.cos(el)
            var_third = var_z  # the third parameter is the height above the sensor
            d_el_dr, d_el_dthird = -height / (r * r * cos_el), 1.0 / (r * cos_el)
        local = np.array(polar_to_cartesian(r, az, el), dtype=float)
        ground = r * math.cos(el)
        sa, ca, se, ce = math.sin(az), math.cos(az), math.sin(el), math.cos(el)
        # Jacobian of (x, y, z)_local with respect to (r, az, el)
        J_rae = np.array([
            [ce * sa, ground * ca, -r * se * sa],
            [ce * ca, -ground * sa, -r * se * ca],
            [se, 0.0, r * ce],
        ])
        # chain to (r, az, third) where third is el itself or the height
        chain = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [d_el_dr, 0.0, d_el_dthird]])
        J_c = J_rae @ chain
        cov_local = J_c @ np.diag([var_r, var_az, var_third]) @ J_c.T
        rot = self.sensor_rotation
        position = local @ rot + self.sensor_position
        return position, rot.T @ cov_local @ rot

    # ---- prediction ---------------------------------------------------------
    def extrapolate(self, dt: float, params=None) -> tuple[np.ndarray, np.ndarray]:
        """Pure Theorem 2 over ``dt`` (R6/R7: extrapolate to a report's own timestamp)."""
        self._require_state()
        F, Q = self.transition(dt, params)
        x, P = predict(self.x[None], self.P[None], F, Q)
        return x[0], P[0]

    def _params_for_step(self, params):
        if params is None and self.coefficient_policy is not None:
            params = self.coefficient_policy(self.history)
        return self._axis_params(params)

    def predict(self, dt: float, params=None):
        """Advance the state by ``dt``; ``params``: SingerParams or three of them (R10). Returns those used."""
        used = self._params_for_step(params)
        self.x, self.P = self.extrapolate(dt, used)
        return used

    # ---- measurement ----------------------------------------------------------
    def _sigma(self, component: str) -> float:
        if component not in self.sigmas:
            raise ValueError(f"no measurement st. dev. configured for component {component!r}")
        return self.sigmas[component]

    @staticmethod
    def _report_values(report: Mapping[str, float]) -> dict[str, float]:
        unknown = set(report) - set(REPORT_COMPONENTS)
        if unknown:
            raise ValueError(f"report has unknown components {sorted(unknown)}; known: {REPORT_COMPONENTS}")
        values = {}
        for key, value in report.items():
            v = float(value)
            if not math.isfinite(v):
                raise ValueError(f"report component {key!r} is not finite: {value!r}")
            values[key] = v
        cart = [c for c in CARTESIAN_COMPONENTS if c in values]
        if cart and len(cart) != 3:
            raise ValueError(f"a Cartesian position needs x, y and z; report has only {cart}")
        return values

    def measurement_components(self, report: Mapping[str, float]) -> tuple[tuple[str, ...], dict[str, float], dict[str, float]]:
        """Components used for ``report`` (R8, R9): (ordered names, values, sigmas), incl. injected altitude."""
        values = self._report_values(report)
        if not self.use_range_rate:
            values.pop("rdot", None)
        sigmas = {c: self._sigma(c) for c in values}
        has_vertical = "el" in values or "z_alt" in values or "x" in values
        if not has_vertical:
            if self.assumed_altitude is None:
                raise ValueError(
                    "report has neither elevation, altitude (z_alt) nor a Cartesian position, "
                    "and the tracker has no assumed_altitude=(z0, sigma_z0)"
                )
            values["z_alt"], sigmas["z_alt"] = self.assumed_altitude
        order = [c for c in REPORT_COMPONENTS if c in values]
        return tuple(order), values, sigmas

    def innovation(self, report: Mapping[str, float], dt: float | None = None, params=None) -> Innovation3D:
        """nu = z - h(x) (angles wrapped to (-pi, pi]), S = J P J^T + R and d^2 (Cholesky) (R7).

        Evaluated at the current state, or, with ``dt``, at its extrapolation to the report's
        own timestamp ``dt`` later (the track itself is not changed).
        """
        self._require_state()
        if dt is None:
            x, P = self.x, self.P
        else:
            x, P = self.extrapolate(dt, self._axis_params(params))
        return self._innovation_at(x, P, report)

    def _innovation_at(self, x: np.ndarray, P: np.ndarray, report: Mapping[str, float]) -> Innovation3D:
        names, values, sigmas = self.measurement_components(report)
        polar = tuple(c for c in names if c in POLAR_COMPONENTS)
        cart = tuple(c for c in names if c in CARTESIAN_COMPONENTS)
        if any(c in ("r", "az", "el", "rdot") for c in polar):
            rel = self.sensor_rotation @ (x[[0, 3, 6]] - self.sensor_position)
            ground = math.hypot(rel[0], rel[1])
            rng = math.hypot(ground, rel[2])
            if rng < MIN_RANGE_M or ground < MIN_RANGE_M or values.get("r", MIN_RANGE_M) < MIN_RANGE_M:
                raise ValueError(
                    f"polar update refused: predicted range {rng:.3f} m / horizontal range {ground:.3f} m "
                    f"or measured range below {MIN_RANGE_M} m"
                )
        h_parts, H_parts, angular = [], [], []
        if polar:
            pm = PolarMeasurementModel(polar, tuple(sigmas[c] for c in polar), order=3)
            h, H = pm.evaluate(x[None], sensor_position=self.sensor_position, rotation=self.sensor_rotation)
            h_parts.append(h[0])
            H_parts.append(H[0])
            angular.extend(pm.angular.tolist())
        if cart:
            cm = CartesianPositionModel(3, 3)
            h, H = cm.evaluate(x[None])
            h_parts.append(h[0])
            H_parts.append(H[0])
            angular.extend([False] * 3)
        h = np.concatenate(h_parts)
        H = np.concatenate(H_parts, axis=0)
        z = np.array([values[c] for c in names])
        angular_mask = np.array(angular, dtype=bool)
        nu = innovation(z, h, angular_mask)
        R = np.diag([sigmas[c] ** 2 for c in names])
        S = symmetrize(H @ P @ H.T + R)
        d2 = float(mahalanobis(nu[None], S[None])[0])
        return Innovation3D(names, z, h, nu, H, R, S, d2, angular_mask)

    def update(self, report: Mapping[str, float]) -> Innovation3D:
        """EKF update with ``report`` at the current state (R8), in the configured ``update_form``."""
        inn = self.innovation(report)
        result = update(self.x[None], self.P[None], inn.nu[None], inn.H[None], inn.R, form=self.update_form)
        self.x, self.P = result.x[0], result.P[0]
        return inn

    def step(self, report: Mapping[str, float] | None, dt: float, params=None) -> Innovation3D | None:
        """One scan: predict over ``dt``, then update with ``report`` or, if it is None, a miss (R4)."""
        dt = _check_dt(dt)
        used = self.predict(dt, params)
        inn = None if report is None else self.update(report)
        self.history.append(dt, used, report is not None, None if report is None else dict(report),
                            self.x.copy(), float("nan") if inn is None else inn.d2)
        return inn

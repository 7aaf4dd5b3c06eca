"""Airborne radar scenario generator of spec 003 (R17) and the E4 crossing scenario (§6).

Geometry: the own-ship (radar carrier) and every target fly scripted constant-velocity legs
in the flat ENU tracking frame (:class:`ConstantVelocityLegs`).  The radar takes one scan
every ``T`` seconds, and all plots of scan ``k`` carry the time ``t_k = k T``.

Per scan and target (R17):

* the target is detected with probability ``p_detection`` (its own value);
* a detected target gives exactly one plot (perfect resolution):
  ``z = h(x_true) + N(0, R)``, with ``h`` the model of :mod:`skytrack.models.airborne`
  evaluated with the own-ship's true state and ``R = diag(sigma_D^2, sigma_az^2,
  sigma_el^2[, sigma_V^2])``; the measured azimuth is taken mod 2 pi;
* the plots of a scan are emitted in a seeded random order;
* optional uniform clutter (off by default): Poisson(``per_scan``) false plots per scan,
  uniform in range, azimuth, elevation and range rate over the configured box; their true
  object is -1.

Random numbers (R18) come from independent streams spawned from the run seed,
``np.random.SeedSequence(seed).spawn(5)``, in this order: measurement noise, detection, plot
order, IFF, clutter.  Noise, detection and order keys are drawn for every (scan, target)
slot whether or not a plot results, so changing ``p_detection`` does not move the noise of
the plots that remain.  The IFF stream is only created here and handed out with the run
(:attr:`AirborneRun.iff_rng`) for the IFF responder; drawing from it never changes the
primary plots, which makes coordinate-only decisions independent of every IFF setting.

True identity per target: the status as an index into
:data:`skytrack.core.plots.IFF_VALUES` (0 friend, 1 foe) and the Mode 3/A code as
``int(code, 8)`` (-1 without a code).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from skytrack.core.plots import IFF_VALUES
from skytrack.models.airborne import airborne_measurement, airborne_noise

_TWO_PI = 2.0 * math.pi
#: statuses a target can truly have (undetermined is a reply or track state, never the truth)
TRUE_STATUSES = ("friend", "foe")


@dataclass(frozen=True)
class ConstantVelocityLegs:
    """Piecewise constant-velocity motion: at ``leg_starts[0]`` the object is at ``start_position``,
    and from ``leg_starts[i]`` on it flies with ``velocities[i]`` (m/s, ENU).

    Before the first leg start the first velocity is extrapolated backwards.
    """

    start_position: tuple[float, float, float]
    leg_starts: tuple[float, ...]
    velocities: tuple[tuple[float, float, float], ...]

    def __post_init__(self):
        starts = np.asarray(self.leg_starts, dtype=float)
        velocities = np.asarray(self.velocities, dtype=float)
        if starts.ndim != 1 or len(starts) == 0 or velocities.shape != (len(starts), 3):
            raise ValueError("one velocity (e, n, u) per leg start is needed")
        if np.any(np.diff(starts) <= 0) or not np.all(np.isfinite(starts)):
            raise ValueError(f"leg start times must be finite and increasing, got {self.leg_starts}")
        if not (np.all(np.isfinite(velocities)) and np.all(np.isfinite(self.start_position))):
            raise ValueError("positions and velocities must be finite")

    @classmethod
    def straight(cls, position, velocity, at_time: float = 0.0) -> "ConstantVelocityLegs":
        """One leg through ``position`` at ``at_time`` with ``velocity``."""
        return cls(tuple(map(float, position)), (float(at_time),), (tuple(map(float, velocity)),))

    def state(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities ``[N, 3]`` at times ``t [N]``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = np.asarray(self.leg_starts, dtype=float)
        velocities = np.asarray(self.velocities, dtype=float)
        # position at each leg start, legs flown one after the other
        knots = np.asarray(self.start_position, dtype=float) + np.concatenate(
            [np.zeros((1, 3)), np.cumsum(np.diff(starts)[:, None] * velocities[:-1], axis=0)])
        leg = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
        velocity = velocities[leg]
        return knots[leg] + (t - starts[leg])[:, None] * velocity, velocity


@dataclass(frozen=True)
class AirborneTarget:
    """A target: motion, detection probability, true IFF status and optional Mode 3/A code."""

    motion: ConstantVelocityLegs
    p_detection: float = 1.0
    iff_status: str = "friend"
    code: str | None = None

    def __post_init__(self):
        if not 0.0 <= self.p_detection <= 1.0:
            raise ValueError(f"p_detection must be in [0, 1], got {self.p_detection}")
        if self.iff_status not in TRUE_STATUSES:
            raise ValueError(f"a target's true status is one of {TRUE_STATUSES}, got {self.iff_status!r}")
        if self.code is not None and (len(self.code) != 4 or any(c not in "01234567" for c in self.code)):
            raise ValueError(f"a Mode 3/A code has 4 octal digits, got {self.code!r}")


@dataclass(frozen=True)
class AirborneRadar:
    """Measurement noise of the airborne radar (standard deviations in m, rad, rad, m/s)."""

    sigma_range_m: float = 30.0
    sigma_az_rad: float = math.radians(0.3)
    sigma_el_rad: float = math.radians(0.3)
    sigma_vr_mps: float = 2.0
    with_range_rate: bool = True

    @property
    def noise(self) -> np.ndarray:
        """``R [m, m]``, m = 4 (or 3 without range rate)."""
        return airborne_noise(self.sigma_range_m, self.sigma_az_rad, self.sigma_el_rad,
                              self.sigma_vr_mps if self.with_range_rate else None, self.with_range_rate)

    @property
    def sigmas(self) -> np.ndarray:
        return np.sqrt(np.diag(self.noise))


@dataclass(frozen=True)
class UniformClutter:
    """Poisson(``per_scan``) false plots per scan, uniform over the (range, azimuth, elevation,
    range rate) box; azimuth over the full circle."""

    per_scan: float = 0.0
    range_m: tuple[float, float] = (1_000.0, 100_000.0)
    el_rad: tuple[float, float] = (-0.2, 0.2)
    vr_mps: tuple[float, float] = (-600.0, 600.0)

    def __post_init__(self):
        if not (math.isfinite(self.per_scan) and self.per_scan >= 0):
            raise ValueError(f"clutter per_scan must be finite and >= 0, got {self.per_scan}")
        for name in ("range_m", "el_rad", "vr_mps"):
            low, high = getattr(self, name)
            if not low <= high:
                raise ValueError(f"clutter {name} must be (low, high) with low <= high")


@dataclass(frozen=True)
class AirborneScenario:
    """Own-ship, targets, radar and scan timing; ``crossing_scan`` is k_c of a crossing (metrics)."""

    own_ship: ConstantVelocityLegs
    targets: tuple[AirborneTarget, ...]
    radar: AirborneRadar = field(default_factory=AirborneRadar)
    scan_period_s: float = 2.0
    n_scans: int = 61
    clutter: UniformClutter | None = None
    crossing_scan: int | None = None

    def __post_init__(self):
        if not (math.isfinite(self.scan_period_s) and self.scan_period_s > 0):
            raise ValueError(f"scan_period_s must be finite and > 0, got {self.scan_period_s}")
        if self.n_scans < 1:
            raise ValueError(f"n_scans must be >= 1, got {self.n_scans}")

    @property
    def scan_times(self) -> np.ndarray:
        return np.arange(self.n_scans) * self.scan_period_s

    def truth(self) -> "AirborneTruth":
        """True own-ship and target states per scan, and the noise-free measurements."""
        t = self.scan_times
        own_p, own_v = self.own_ship.state(t)
        states = np.empty((self.n_scans, len(self.targets), 6))
        for j, target in enumerate(self.targets):
            states[:, j, :3], states[:, j, 3:] = target.motion.state(t)
        pair_own_p = np.repeat(own_p, len(self.targets), axis=0)
        pair_own_v = np.repeat(own_v, len(self.targets), axis=0)
        h = airborne_measurement(states.reshape(-1, 6), pair_own_p, pair_own_v,
                                 self.radar.with_range_rate, jacobian=False)
        return AirborneTruth(t, own_p, own_v, states, h.reshape(self.n_scans, len(self.targets), -1))


@dataclass
class AirborneTruth:
    """Per scan ``k``: time ``t [K]``, own-ship ``own_p``, ``own_v`` ``[K, 3]``, target states
    ``[K, J, 6]`` (e, n, u, v_e, v_n, v_u) and noise-free measurements ``h [K, J, m]``."""

    t: np.ndarray
    own_p: np.ndarray
    own_v: np.ndarray
    states: np.ndarray
    h: np.ndarray


class AirborneStreams(NamedTuple):
    """The run's independent random streams (R18), in spawn order."""

    noise: np.random.Generator
    detection: np.random.Generator
    order: np.random.Generator
    iff: np.random.Generator
    clutter: np.random.Generator


def spawn_streams(seed) -> AirborneStreams:
    """Spawn the run's streams from ``seed`` (an int or a ``SeedSequence``, which is not consumed)."""
    if isinstance(seed, np.random.SeedSequence):
        base = np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key, pool_size=seed.pool_size)
    else:
        base = np.random.SeedSequence(seed)
    return AirborneStreams(*(np.random.default_rng(child) for child in base.spawn(len(AirborneStreams._fields))))


@dataclass
class AirborneRun:
    """One simulated run: plots sorted by scan, in the scan's random order.

    Per plot: ``scan``, ``t``, ``range_m``, ``az`` (in [0, 2 pi)), ``el``, ``vr`` (NaN without
    range rate), own-ship ``own_p``, ``own_v`` ``[N, 3]`` at ``t``, and the true object
    ``truth`` (index into the targets; -1 for clutter).  Per target: true status
    ``target_status`` (0 friend, 1 foe) and ``target_code`` (``int(code, 8)``, -1 without).
    ``noise`` is R, ``iff_rng`` the run's IFF stream, ``true`` the scenario's truth.
    """

    scan: np.ndarray
    t: np.ndarray
    range_m: np.ndarray
    az: np.ndarray
    el: np.ndarray
    vr: np.ndarray
    own_p: np.ndarray
    own_v: np.ndarray
    truth: np.ndarray
    target_status: np.ndarray
    target_code: np.ndarray
    noise: np.ndarray
    iff_rng: np.random.Generator
    true: AirborneTruth

    def __len__(self) -> int:
        return len(self.t)

    @property
    def measurements(self) -> np.ndarray:
        """``z [N, m]``: (range, az, el, vr), or without ``vr`` when the radar has no range rate."""
        columns = [self.range_m, self.az, self.el] + ([self.vr] if self.noise.shape[-1] == 4 else [])
        return np.column_stack(columns)


def _wrap_azimuth(az: np.ndarray) -> np.ndarray:
    wrapped = np.remainder(az, _TWO_PI)
    # remainder of a tiny negative angle rounds to 2 pi itself; that direction is north
    return np.where(wrapped >= _TWO_PI, 0.0, wrapped)


def _clutter(clutter: UniformClutter | None, n_scans: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Scan index ``[C]`` and (range, az, el, vr) ``[C, 4]`` of the false plots."""
    if clutter is None or clutter.per_scan == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4))
    counts = rng.poisson(clutter.per_scan, n_scans)
    scans = np.repeat(np.arange(n_scans), counts)
    boxes = np.array([clutter.range_m, (0.0, _TWO_PI), clutter.el_rad, clutter.vr_mps])
    values = boxes[:, 0] + rng.random((len(scans), 4)) * (boxes[:, 1] - boxes[:, 0])
    values[:, 1] = _wrap_azimuth(values[:, 1])
    return scans, values


def simulate_airborne(scenario: AirborneScenario, seed, truth: AirborneTruth | None = None) -> AirborneRun:
    """Simulate one run of ``scenario`` from ``seed``; pass ``truth`` (``scenario.truth()``) to reuse it."""
    truth = scenario.truth() if truth is None else truth
    streams = spawn_streams(seed)
    n_scans, n_targets, m = truth.h.shape
    sigmas = scenario.radar.sigmas

    measured = truth.h + streams.noise.standard_normal((n_scans, n_targets, m)) * sigmas
    measured[..., 1] = _wrap_azimuth(measured[..., 1])
    p_detection = np.array([target.p_detection for target in scenario.targets])
    detected = streams.detection.random((n_scans, n_targets)) < p_detection
    target_keys = streams.order.random((n_scans, n_targets))
    clutter_scans, clutter_values = _clutter(scenario.clutter, n_scans, streams.clutter)
    clutter_keys = streams.order.random(len(clutter_scans))

    scan_of_slot, target_of_slot = np.nonzero(detected)
    plot_values = measured[detected]
    if m == 3:
        plot_values = np.column_stack([plot_values, np.full(len(plot_values), np.nan)])
        clutter_values = clutter_values.copy()
        clutter_values[:, 3] = np.nan
    scan = np.concatenate([scan_of_slot, clutter_scans])
    values = np.concatenate([plot_values, clutter_values])
    obj = np.concatenate([target_of_slot, np.full(len(clutter_scans), -1)])
    keys = np.concatenate([target_keys[detected], clutter_keys])
    order = np.lexsort((keys, scan))
    scan, values, obj = scan[order], values[order], obj[order]

    statuses = np.array([IFF_VALUES.index(target.iff_status) for target in scenario.targets], dtype=np.int64)
    codes = np.array([int(target.code, 8) if target.code is not None else -1 for target in scenario.targets],
                     dtype=np.int64)
    return AirborneRun(
        scan=scan, t=truth.t[scan], range_m=values[:, 0], az=values[:, 1], el=values[:, 2], vr=values[:, 3],
        own_p=truth.own_p[scan], own_v=truth.own_v[scan], truth=obj, target_status=statuses,
        target_code=codes, noise=scenario.radar.noise, iff_rng=streams.iff, true=truth,
    )


def crossing_scenario(
    beta_deg: float = 5.0,
    d_e: float = 0.0,
    dh: float = 0.0,
    *,
    speed_mps: float = 250.0,
    own_start: tuple[float, float, float] = (0.0, 0.0, 8000.0),
    own_velocity: tuple[float, float, float] = (0.0, 250.0, 0.0),
    crossing_point: tuple[float, float, float] = (0.0, 55_000.0, 6000.0),
    crossing_time_s: float = 60.0,
    scan_period_s: float = 2.0,
    n_scans: int = 61,
    p_detection: float = 1.0,
    radar: AirborneRadar | None = None,
    clutter: UniformClutter | None = None,
    target_a: tuple[str, str | None] = ("friend", "1234"),
    target_b: tuple[str, str | None] = ("foe", "5670"),
) -> AirborneScenario:
    """The E4 reference scenario of spec 003 §6 (defaults = the table's values).

    The own-ship starts at (0, 0, 8000) m flying north at 250 m/s; scans every 2 s,
    k = 0..60; radar sigmas 30 m, 0.3 deg, 0.3 deg, 2 m/s; P_D = 1; no clutter.

    Reading of "heading +beta / -beta": both targets fly level at ``speed_mps`` **toward the
    own-ship**, roughly south (the carrier flies north), each on a track turned by ``beta``
    from due south: A (heading +beta) has velocity ``v (sin beta, -cos beta, 0)`` (course
    180 deg - beta, coming from the west of the crossing point), B (heading -beta) has
    ``v (-sin beta, -cos beta, 0)`` (course 180 deg + beta, from the east).  A passes the
    crossing point C at ``crossing_time_s`` (t_c = 60 s, scan k_c = 30), B passes
    C + (d_e, 0, dh) at the same time, so with d_e = dh = 0 they cross at C, closing on the
    own-ship at about 500 m/s; with beta = 0 they fly parallel, d_e apart.  At t_c the
    own-ship is at (0, 15 000, 8000), 40 km short of C.

    Target A is friend "1234", B foe "5670" (``target_a`` / ``target_b`` = (status, code)).
    """
    beta = math.radians(beta_deg)
    crossing = np.asarray(crossing_point, dtype=float)
    velocity_a = speed_mps * np.array([math.sin(beta), -math.cos(beta), 0.0])
    velocity_b = speed_mps * np.array([-math.sin(beta), -math.cos(beta), 0.0])
    a = AirborneTarget(ConstantVelocityLegs.straight(crossing, velocity_a, crossing_time_s), p_detection, *target_a)
    b = AirborneTarget(ConstantVelocityLegs.straight(crossing + [d_e, 0.0, dh], velocity_b, crossing_time_s),
                       p_detection, *target_b)
    crossing_scan = crossing_time_s / scan_period_s
    return AirborneScenario(
        own_ship=ConstantVelocityLegs.straight(own_start, own_velocity, 0.0),
        targets=(a, b),
        radar=AirborneRadar() if radar is None else radar,
        scan_period_s=scan_period_s,
        n_scans=n_scans,
        clutter=clutter,
        crossing_scan=int(round(crossing_scan)) if float(crossing_scan).is_integer() else None,
    )

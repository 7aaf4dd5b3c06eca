"""Target trajectories: scripted legs turned into exact piecewise-analytic motion.

Each target's horizontal motion in the common ENU plane is a chain of *pieces*:

* polynomial pieces ``x(tau) = c0 + c1 tau + c2 tau^2 + c3 tau^3`` (same for y): straight
  flight, constant tangential acceleration (``accelerate`` legs) and the cubic-Hermite
  links between the nodes of a Singer leg;
* circular arcs (coordinated turns): centre ``C``, radius ``rho = v^2 / (n g)``, bearing
  from the centre ``theta(tau) = theta0 + omega tau`` with ``omega = +-n g / v``
  (positive = right turn, clockwise), position ``C + rho (sin theta, cos theta)``,
  velocity ``rho omega (cos theta, -sin theta)``.  These are exact arcs, not Euler steps.

The height above the ellipsoid is linear within a piece (``h0 + hdot tau``).  ENU ``z``,
latitude/longitude and ``vz`` follow from (x, y, h) with :mod:`skytrack.sim.earth`,
so ``z`` includes the Earth's curvature.

A ``land`` leg is a straight descent at its rate to the field height; the target's
``end_time`` is the touchdown (no truth and no plots after it).

Singer legs (spec 000, section 3.3, X1-X2): acceleration on each horizontal axis is
the stationary first-order Markov process of the Singer model, sampled exactly every
``SINGER_STEP_S`` with :class:`skytrack.models.SingerAxisModel` (``exact``
discretisation: transition F_S and noise covariance Q_S), the speed being kept within a
range by removing the outward acceleration at a node where the speed leaves it.

All targets' pieces live in flat arrays (structure of arrays) so that
:meth:`TrajectorySet.evaluate` is vectorised over any batch of (target, time) pairs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from skytrack.geo.sensors import Origin
from skytrack.models.motion import SingerAxisModel
from skytrack.sim.earth import place_at_height, vertical_velocity
from skytrack.sim.spec import (
    GRAVITY_MPS2,
    AccelerateLeg,
    ClimbLeg,
    LandLeg,
    SingerLeg,
    StraightLeg,
    TargetSpec,
    TurnLeg,
    WaypointsLeg,
)

POLY, ARC = 0, 1
#: node spacing of Singer legs (s); pieces between nodes are cubic Hermite
SINGER_STEP_S = 1.0
#: default speed band of a Singer leg relative to the speed at its start
SINGER_SPEED_BAND = (0.7, 1.3)
_TWO_PI = 2.0 * math.pi


@dataclass
class _FlightState:
    t: float
    x: float
    y: float
    h: float
    speed: float
    heading: float  # rad, clockwise from north


@dataclass
class _PieceLists:
    target: list = field(default_factory=list)
    t0: list = field(default_factory=list)
    kind: list = field(default_factory=list)
    coef: list = field(default_factory=list)
    h0: list = field(default_factory=list)
    hdot: list = field(default_factory=list)

    def add(self, target: int, t0, kind, coef, h0, hdot) -> None:
        """Append one piece (scalars) or a block of pieces (arrays, ``coef`` of shape [k, 8])."""
        t0 = np.atleast_1d(np.asarray(t0, dtype=float))
        k = t0.size
        self.target.append(np.full(k, target, dtype=np.int64))
        self.t0.append(t0)
        self.kind.append(np.full(k, kind, dtype=np.int8))
        self.coef.append(np.asarray(coef, dtype=float).reshape(k, 8))
        self.h0.append(np.broadcast_to(np.asarray(h0, dtype=float), (k,)))
        self.hdot.append(np.broadcast_to(np.asarray(hdot, dtype=float), (k,)))


@dataclass
class TrajectorySet:
    """All targets' trajectories as flat piece arrays; see the module docstring."""

    ids: np.ndarray  # [N] object (str)
    start_time: np.ndarray  # [N]
    end_time: np.ndarray  # [N] last instant simulated (touchdown of a land leg; truncated when the target leaves coverage)
    legs_end_time: np.ndarray  # [N] end of the last scripted leg (capped at the duration)
    transponder: np.ndarray  # [N] bool
    mode3a: np.ndarray  # [N] object, None when absent
    icao24: np.ndarray  # [N] object, None when absent
    origin: Origin
    piece_target: np.ndarray
    piece_t0: np.ndarray
    piece_kind: np.ndarray
    piece_coef: np.ndarray  # [P, 8]
    piece_h0: np.ndarray
    piece_hdot: np.ndarray
    first_piece: np.ndarray  # [N]
    last_piece: np.ndarray  # [N]
    time_span: float  # > any time queried; orders (target, time) keys
    _piece_keys: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._piece_keys = self.piece_target * self.time_span + self.piece_t0

    def __len__(self) -> int:
        return len(self.ids)

    def _piece_index(self, target: np.ndarray, t: np.ndarray) -> np.ndarray:
        index = np.searchsorted(self._piece_keys, target * self.time_span + t, side="right") - 1
        return np.clip(index, self.first_piece[target], self.last_piece[target])

    def evaluate(self, target, t) -> tuple[np.ndarray, ...]:
        """Horizontal ENU position/velocity and height: ``(x, y, h, vx, vy, hdot)`` at ``t``."""
        target = np.asarray(target, dtype=np.int64)
        t = np.asarray(t, dtype=float)
        piece = self._piece_index(target, t)
        tau = t - self.piece_t0[piece]
        out = [np.empty(t.shape) for _ in range(4)]
        kind = self.piece_kind[piece]
        for which, mask in ((POLY, kind == POLY), (ARC, kind == ARC)):
            if not mask.any():
                continue
            c = self.piece_coef[piece[mask]]
            s = tau[mask]
            if which == POLY:
                out[0][mask] = c[:, 0] + s * (c[:, 1] + s * (c[:, 2] + s * c[:, 3]))
                out[1][mask] = c[:, 4] + s * (c[:, 5] + s * (c[:, 6] + s * c[:, 7]))
                out[2][mask] = c[:, 1] + s * (2.0 * c[:, 2] + 3.0 * s * c[:, 3])
                out[3][mask] = c[:, 5] + s * (2.0 * c[:, 6] + 3.0 * s * c[:, 7])
            else:
                theta = c[:, 3] + c[:, 4] * s
                sin_t, cos_t = np.sin(theta), np.cos(theta)
                out[0][mask] = c[:, 0] + c[:, 2] * sin_t
                out[1][mask] = c[:, 1] + c[:, 2] * cos_t
                out[2][mask] = c[:, 2] * c[:, 4] * cos_t
                out[3][mask] = -c[:, 2] * c[:, 4] * sin_t
        hdot = self.piece_hdot[piece]
        h = self.piece_h0[piece] + hdot * tau
        return out[0], out[1], h, out[2], out[3], hdot

    def state(self, target, t) -> dict[str, np.ndarray]:
        """Full ENU + geodetic state at ``t``: x, y, z, vx, vy, vz, lat, lon, alt_m."""
        x, y, h, vx, vy, hdot = self.evaluate(target, t)
        z, lat, lon, up = place_at_height(x, y, h, self.origin)
        vz = vertical_velocity(vx, vy, hdot, up)
        return {"x": x, "y": y, "z": z, "vx": vx, "vy": vy, "vz": vz, "lat": lat, "lon": lon, "alt_m": h}


def build_trajectories(targets: list[TargetSpec], duration_s: float, origin: Origin, rng: np.random.Generator) -> TrajectorySet:
    """Fly every target's legs; ``rng`` drives the Singer legs (targets in order, reproducible)."""
    pieces = _PieceLists()
    n = len(targets)
    start = np.array([t.start_time_s for t in targets], dtype=float)
    legs_end = np.empty(n)
    end = np.full(n, float(duration_s))
    for j, target in enumerate(targets):
        state = _FlightState(
            target.start_time_s, target.x, target.y, target.alt_m, target.speed_mps, math.radians(target.heading_deg)
        )
        for leg in target.legs:
            if state.t >= duration_s:
                break
            state = _fly_leg(pieces, j, state, leg, rng)
            if isinstance(leg, LandLeg):  # the last leg (parser): the flight ends at touchdown
                end[j] = min(state.t, duration_s)
        legs_end[j] = min(state.t, duration_s)
        # level flight to the end of the run; after a touchdown it only serves evaluations just
        # past end_time (beam-crossing refinement), whose plots are dropped
        _line(pieces, j, state, max(duration_s - state.t, 0.0))
    if n:
        arrays = {name: np.concatenate(getattr(pieces, name)) for name in ("target", "t0", "kind", "coef", "h0", "hdot")}
    else:
        arrays = {"target": np.zeros(0, np.int64), "t0": np.zeros(0), "kind": np.zeros(0, np.int8),
                  "coef": np.zeros((0, 8)), "h0": np.zeros(0), "hdot": np.zeros(0)}
    first = np.searchsorted(arrays["target"], np.arange(n), side="left")
    last = np.searchsorted(arrays["target"], np.arange(n), side="right") - 1
    return TrajectorySet(
        ids=np.array([t.id for t in targets], dtype=object),
        start_time=start,
        end_time=end,
        legs_end_time=legs_end,
        transponder=np.array([t.transponder for t in targets], dtype=bool),
        mode3a=np.array([t.mode3a for t in targets], dtype=object),
        icao24=np.array([t.icao24 for t in targets], dtype=object),
        origin=origin,
        piece_target=arrays["target"],
        piece_t0=arrays["t0"],
        piece_kind=arrays["kind"],
        piece_coef=arrays["coef"],
        piece_h0=arrays["h0"],
        piece_hdot=arrays["hdot"],
        first_piece=first,
        last_piece=last,
        time_span=2.0 ** math.ceil(math.log2(max(duration_s, float(arrays["t0"].max(initial=0.0))) + 2.0)) * 4.0,
    )


# ---------------------------------------------------------------------------------------
# Leg geometry
# ---------------------------------------------------------------------------------------


def _fly_leg(p: _PieceLists, j: int, s: _FlightState, leg, rng: np.random.Generator) -> _FlightState:
    if isinstance(leg, StraightLeg):
        return _line(p, j, s, leg.duration_s)
    if isinstance(leg, TurnLeg):
        sign = 1.0 if leg.direction == "right" else -1.0
        omega = sign * leg.g * GRAVITY_MPS2 / s.speed
        duration = leg.duration_s if leg.duration_s is not None else math.radians(leg.turn_deg) / abs(omega)
        return _arc(p, j, s, omega, duration)
    if isinstance(leg, ClimbLeg):
        if leg.to_alt_m is None:
            return _line(p, j, s, leg.duration_s, hdot=leg.rate_mps)
        change = leg.to_alt_m - s.h
        if change == 0.0:
            return s
        return _line(p, j, s, abs(change) / leg.rate_mps, hdot=math.copysign(leg.rate_mps, change), h_end=leg.to_alt_m)
    if isinstance(leg, AccelerateLeg):
        change = leg.to_speed_mps - s.speed
        if change == 0.0:
            return s
        return _line(p, j, s, abs(change) / leg.rate_mps2, accel=math.copysign(leg.rate_mps2, change), v_end=leg.to_speed_mps)
    if isinstance(leg, SingerLeg):
        return _singer(p, j, s, leg, rng)
    if isinstance(leg, WaypointsLeg):
        for point in leg.points:
            s = _fly_to(p, j, s, point.x, point.y, point.alt_m, leg.max_g)
        return s
    if isinstance(leg, LandLeg):
        drop = s.h - leg.field_alt_m
        if drop <= 0.0:  # already at (or below) the field: touchdown now
            return s
        return _line(p, j, s, drop / leg.rate_mps, hdot=-leg.rate_mps, h_end=leg.field_alt_m)
    raise TypeError(f"unknown leg {leg!r}")  # pragma: no cover - the loader only builds the types above


def _line(p: _PieceLists, j: int, s: _FlightState, duration: float, hdot: float = 0.0, accel: float = 0.0,
          h_end: float | None = None, v_end: float | None = None) -> _FlightState:
    """Straight flight along the heading, optionally accelerating and climbing."""
    ux, uy = math.sin(s.heading), math.cos(s.heading)
    p.add(j, s.t, POLY, [s.x, s.speed * ux, 0.5 * accel * ux, 0.0, s.y, s.speed * uy, 0.5 * accel * uy, 0.0], s.h, hdot)
    travel = s.speed * duration + 0.5 * accel * duration * duration
    return _FlightState(
        s.t + duration,
        s.x + travel * ux,
        s.y + travel * uy,
        s.h + hdot * duration if h_end is None else h_end,
        s.speed + accel * duration if v_end is None else v_end,
        s.heading,
    )


def _arc(p: _PieceLists, j: int, s: _FlightState, omega: float, duration: float, hdot: float = 0.0) -> _FlightState:
    """Coordinated turn at rate ``omega`` (rad/s, > 0 = right) for ``duration`` seconds."""
    radius = s.speed / abs(omega)
    sign = math.copysign(1.0, omega)
    cx = s.x + sign * radius * math.cos(s.heading)
    cy = s.y - sign * radius * math.sin(s.heading)
    theta0 = s.heading - sign * 0.5 * math.pi
    p.add(j, s.t, ARC, [cx, cy, radius, theta0, omega, 0.0, 0.0, 0.0], s.h, hdot)
    theta = theta0 + omega * duration
    return _FlightState(
        s.t + duration,
        cx + radius * math.sin(theta),
        cy + radius * math.cos(theta),
        s.h + hdot * duration,
        s.speed,
        math.remainder(s.heading + omega * duration, _TWO_PI) % _TWO_PI,
    )


def _fly_to(p: _PieceLists, j: int, s: _FlightState, wx: float, wy: float, walt: float | None, max_g: float) -> _FlightState:
    """Turn at ``max_g`` towards a waypoint, then fly straight through it (shorter of left/right)."""
    radius = s.speed**2 / (max_g * GRAVITY_MPS2)
    best = None
    for sign in (1.0, -1.0):  # right, left
        cx = s.x + sign * radius * math.cos(s.heading)
        cy = s.y - sign * radius * math.sin(s.heading)
        dx, dy = wx - cx, wy - cy
        dist = math.hypot(dx, dy)
        if dist <= radius:
            continue  # inside this turning circle: reachable only by the other direction
        final_heading = math.atan2(dx, dy) + sign * math.asin(radius / dist)
        turn = (sign * (final_heading - s.heading)) % _TWO_PI
        if turn > _TWO_PI - 1e-12:
            turn = 0.0
        straight = math.sqrt(dist * dist - radius * radius)
        length = radius * turn + straight
        if best is None or length < best[0]:
            best = (length, sign, turn, straight)
    if best is None:  # the waypoint is where the target already is
        return s
    length, sign, turn, straight = best
    hdot = 0.0 if walt is None else (walt - s.h) * s.speed / length
    if turn > 0.0:
        omega = sign * s.speed / radius
        s = _arc(p, j, s, omega, turn / abs(omega), hdot=hdot)
    s = _line(p, j, s, straight / s.speed, hdot=hdot, h_end=walt)
    return s


def _noise_factor(cov: np.ndarray) -> np.ndarray:
    """Symmetric square root of positive semi-definite matrices ``[..., 3, 3]``."""
    values, vectors = np.linalg.eigh(cov)
    return vectors * np.sqrt(np.clip(values, 0.0, None))[..., None, :]


def _singer(p: _PieceLists, j: int, s: _FlightState, leg: SingerLeg, rng: np.random.Generator) -> _FlightState:
    """Exact Singer acceleration per horizontal axis, nodes every SINGER_STEP_S, cubic Hermite between."""
    steps = np.full(int(math.ceil(leg.duration_s / SINGER_STEP_S - 1e-9)), SINGER_STEP_S)
    steps[-1] = leg.duration_s - SINGER_STEP_S * (len(steps) - 1)
    model = SingerAxisModel(leg.tau_s, leg.sigma_a_mps2, "exact")
    lengths, which = np.unique(steps, return_inverse=True)  # all steps but the last are equal
    transition = model.F_batch(lengths)[which]
    factor = _noise_factor(model.Q_batch(lengths))[which]
    low, high = leg.speed_range_mps or (SINGER_SPEED_BAND[0] * s.speed, SINGER_SPEED_BAND[1] * s.speed)
    # axis-major state [2 axes, (position, velocity, acceleration)]
    state = np.array(
        [
            [s.x, s.speed * math.sin(s.heading), 0.0],
            [s.y, s.speed * math.cos(s.heading), 0.0],
        ]
    )
    state[:, 2] = leg.sigma_a_mps2 * rng.standard_normal(2)  # stationary start of the Markov acceleration
    noise = np.einsum("kaj,kij->kai", rng.standard_normal((len(steps), 2, 3)), factor)
    transition_t = transition.transpose(0, 2, 1)
    nodes = np.empty((len(steps) + 1, 2, 2))
    nodes[0] = state[:, :2]
    for k in range(len(steps)):  # sequential: the speed band feeds back into the state
        state = state @ transition_t[k] + noise[k]
        _keep_speed(state, low, high)
        nodes[k + 1] = state[:, :2]
    t_nodes = s.t + np.concatenate([[0.0], np.cumsum(steps)])
    p0, v0 = nodes[:-1, :, 0], nodes[:-1, :, 1]
    p1, v1 = nodes[1:, :, 0], nodes[1:, :, 1]
    dt = steps[:, None]
    c2 = (3.0 * (p1 - p0) / dt - 2.0 * v0 - v1) / dt
    c3 = (2.0 * (p0 - p1) / dt + v0 + v1) / dt**2
    coef = np.stack([p0[:, 0], v0[:, 0], c2[:, 0], c3[:, 0], p0[:, 1], v0[:, 1], c2[:, 1], c3[:, 1]], axis=1)
    p.add(j, t_nodes[:-1], POLY, coef, s.h, 0.0)
    end_position, end_velocity = nodes[-1, :, 0], nodes[-1, :, 1]
    return _FlightState(
        float(t_nodes[-1]),
        float(end_position[0]),
        float(end_position[1]),
        s.h,
        float(np.hypot(*end_velocity)),
        math.atan2(end_velocity[0], end_velocity[1]) % _TWO_PI,
    )


def _keep_speed(state: np.ndarray, low: float, high: float) -> None:
    """Clamp the horizontal speed into [low, high] and drop the acceleration pushing it out."""
    velocity = state[:, 1]
    speed = math.hypot(velocity[0], velocity[1])
    if low <= speed <= high or speed == 0.0:
        return
    direction = velocity / speed
    along = float(direction @ state[:, 2])
    state[:, 1] = direction * (high if speed > high else low)
    if (speed > high and along > 0.0) or (speed < low and along < 0.0):
        state[:, 2] -= along * direction

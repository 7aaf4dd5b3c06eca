"""Exact scripted 3-D trajectories for the manoeuvring-target studies (spec 004 R19, §6).

A trajectory is a chain of legs flown from an initial ENU position and velocity, in the flat
ENU frame of a radar at the origin (the studies' geometry; no Earth curvature).  Every leg is
one closed-form piece, so sampling at any instant is exact (no integration drift):

* ``straight`` — constant velocity;
* ``accelerate`` — constant acceleration ``a`` along the velocity at the leg's start
  (longitudinal acceleration): ``p = p0 + v0 t + a t^2 / 2``;
* ``turn`` (horizontal coordinated turn) and ``pull_up`` (turn in the vertical plane) — the
  velocity rotates about a fixed unit axis ``u`` at rate ``omega``: with ``v0 = v_par + v_perp``
  (parallel / perpendicular to ``u``) and ``w = u x v_perp``,
  ``p(t) = p0 + v_par t + (sin wt / omega) v_perp + ((1 - cos wt) / omega) w``,
  ``v(t) = v_par + cos(wt) v_perp + sin(wt) w``, ``a(t) = omega u x v(t)``; the load
  ``|a| = omega |v_perp| = n g0`` fixes ``omega``.  A left horizontal turn is ``u = +z``; a
  pull-up is ``u = v x z / |v x z|`` (the acceleration points up for a level start).

The manoeuvres of a scripted trajectory are its runs of consecutive non-straight legs: onset
at the first one's start, end at the last one's end (the ``vertical`` scenario's pull-up and
the following longitudinal acceleration are one manoeuvre).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: standard gravity g0 (spec 004 §2)
G0 = 9.80665
LEG_TYPES = ("straight", "turn", "pull_up", "accelerate")
_LINEAR, _ROTATION = 0, 1


@dataclass(frozen=True)
class Leg:
    """One scripted leg; see the module docstring for the types.

    ``g``: load n (turns: centripetal acceleration n g0; ``accelerate``: n g0 along the
    velocity, negative to decelerate).  A turn needs exactly one of ``duration_s`` and
    ``turn_deg``; the other legs need ``duration_s``.  ``direction``: ``left``/``right``
    (turn) or ``up``/``down`` (pull_up).
    """

    type: str
    duration_s: float | None = None
    g: float = 0.0
    turn_deg: float | None = None
    direction: str = "left"

    def __post_init__(self) -> None:
        if self.type not in LEG_TYPES:
            raise ValueError(f"leg type must be one of {LEG_TYPES}, got {self.type!r}")
        if self.type in ("turn", "pull_up"):
            if (self.duration_s is None) == (self.turn_deg is None):
                raise ValueError(f"a {self.type} leg needs exactly one of duration_s or turn_deg")
            if not (math.isfinite(self.g) and self.g > 0):
                raise ValueError(f"a {self.type} leg needs g > 0, got {self.g}")
            allowed = ("left", "right") if self.type == "turn" else ("up", "down")
            if self.direction not in allowed:
                raise ValueError(f"{self.type} direction must be one of {allowed}, got {self.direction!r}")
            if self.turn_deg is not None and not (math.isfinite(self.turn_deg) and self.turn_deg > 0):
                raise ValueError(f"turn_deg must be > 0, got {self.turn_deg}")
        else:
            if self.duration_s is None:
                raise ValueError(f"a {self.type} leg needs duration_s")
            if self.turn_deg is not None:
                raise ValueError(f"turn_deg is only for turn and pull_up legs, not {self.type}")
            if not math.isfinite(self.g):
                raise ValueError(f"leg g must be finite, got {self.g}")
        if self.duration_s is not None and not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"leg duration_s must be > 0, got {self.duration_s}")

    @property
    def is_maneuver(self) -> bool:
        return self.type != "straight" and self.g != 0.0


def straight(duration_s: float) -> Leg:
    return Leg("straight", duration_s)


def turn(g: float, turn_deg: float | None = None, direction: str = "left", duration_s: float | None = None) -> Leg:
    return Leg("turn", duration_s, g, turn_deg, direction)


def pull_up(g: float, duration_s: float | None = None, direction: str = "up", turn_deg: float | None = None) -> Leg:
    return Leg("pull_up", duration_s, g, turn_deg, direction)


def accelerate(g: float, duration_s: float) -> Leg:
    return Leg("accelerate", duration_s, g)


@dataclass(frozen=True)
class Kinematics:
    """Truth at given instants: ``time[K]``, ``position/velocity/acceleration[K, 3]`` (ENU, SI)."""

    time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    def __len__(self) -> int:
        return len(self.time)


@dataclass(frozen=True)
class ScriptedTrajectory:
    """Legs flown from ``position``/``velocity`` at t = 0, as closed-form pieces."""

    start_position: np.ndarray
    start_velocity: np.ndarray
    legs: tuple[Leg, ...]
    piece_t0: np.ndarray  # [L] start time of each leg
    piece_t1: np.ndarray  # [L] end time
    piece_kind: np.ndarray  # [L] _LINEAR or _ROTATION
    piece_p0: np.ndarray  # [L, 3]
    piece_v0: np.ndarray  # [L, 3]
    piece_a: np.ndarray  # [L, 3] constant acceleration (linear pieces)
    piece_axis: np.ndarray  # [L, 3] rotation axis u (rotation pieces)
    piece_omega: np.ndarray  # [L] rotation rate (rad/s, > 0)

    @property
    def duration_s(self) -> float:
        return float(self.piece_t1[-1])

    def maneuvers(self) -> list[tuple[float, float]]:
        """(onset, end) of each run of consecutive manoeuvre legs, in seconds."""
        out: list[tuple[float, float]] = []
        current: list[float] | None = None
        for leg, t0, t1 in zip(self.legs, self.piece_t0, self.piece_t1):
            if leg.is_maneuver:
                if current is None:
                    current = [float(t0), float(t1)]
                else:
                    current[1] = float(t1)
            elif current is not None:
                out.append((current[0], current[1]))
                current = None
        if current is not None:
            out.append((current[0], current[1]))
        return out

    def evaluate(self, times) -> Kinematics:
        """Exact position, velocity and acceleration at ``times`` (s; clipped to the flight)."""
        t = np.atleast_1d(np.asarray(times, dtype=float))
        if np.any(t < -1e-9) or np.any(t > self.duration_s + 1e-9):
            raise ValueError(f"trajectory times must lie in [0, {self.duration_s:g}] s")
        piece = np.clip(np.searchsorted(self.piece_t0, t, side="right") - 1, 0, len(self.legs) - 1)
        tau = (t - self.piece_t0[piece])[:, None]
        p0, v0 = self.piece_p0[piece], self.piece_v0[piece]
        position = np.empty((t.size, 3))
        velocity = np.empty((t.size, 3))
        acceleration = np.empty((t.size, 3))
        linear = self.piece_kind[piece] == _LINEAR
        if linear.any():
            a = self.piece_a[piece[linear]]
            s = tau[linear]
            position[linear] = p0[linear] + v0[linear] * s + 0.5 * a * s * s
            velocity[linear] = v0[linear] + a * s
            acceleration[linear] = a
        rot = ~linear
        if rot.any():
            u = self.piece_axis[piece[rot]]
            omega = self.piece_omega[piece[rot]][:, None]
            p, v, a = _rotation(p0[rot], v0[rot], u, omega, tau[rot])
            position[rot], velocity[rot], acceleration[rot] = p, v, a
        return Kinematics(t, position, velocity, acceleration)


def _rotation(p0, v0, u, omega, tau):
    """Closed-form motion of a velocity rotating about ``u`` at ``omega`` (module docstring)."""
    v_par = np.sum(v0 * u, axis=-1, keepdims=True) * u
    v_perp = v0 - v_par
    w = np.cross(u, v_perp)
    angle = omega * tau
    s, c = np.sin(angle), np.cos(angle)
    position = p0 + v_par * tau + (s / omega) * v_perp + ((1.0 - c) / omega) * w
    velocity = v_par + c * v_perp + s * w
    acceleration = omega * np.cross(u, velocity)
    return position, velocity, acceleration


def fly(start_position, start_velocity, legs) -> ScriptedTrajectory:
    """Fly ``legs`` from the start state (ENU m, m/s) into a :class:`ScriptedTrajectory`."""
    p = np.asarray(start_position, dtype=float).reshape(3).copy()
    v = np.asarray(start_velocity, dtype=float).reshape(3).copy()
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
        raise ValueError("trajectory start position and velocity must be finite")
    if np.linalg.norm(v) <= 0:
        raise ValueError("trajectory start velocity must be non-zero")
    legs = tuple(legs)
    if not legs:
        raise ValueError("a trajectory needs at least one leg")
    t = 0.0
    rows = {name: [] for name in ("t0", "t1", "kind", "p0", "v0", "a", "axis", "omega")}
    for index, leg in enumerate(legs):
        accel = np.zeros(3)
        axis = np.zeros(3)
        omega = 0.0
        kind = _LINEAR
        if leg.type == "accelerate":
            accel = leg.g * G0 * v / np.linalg.norm(v)
            duration = float(leg.duration_s)
            speed_end = np.linalg.norm(v) + leg.g * G0 * duration
            if speed_end <= 0:
                raise ValueError(f"leg {index}: the deceleration stops the target (speed {speed_end:.1f} m/s at the end)")
        elif leg.type in ("turn", "pull_up"):
            kind = _ROTATION
            axis = _turn_axis(leg, v, index)
            v_perp = v - np.dot(v, axis) * axis
            omega = leg.g * G0 / np.linalg.norm(v_perp)
            duration = float(leg.duration_s) if leg.duration_s is not None else math.radians(leg.turn_deg) / omega
        else:
            duration = float(leg.duration_s)
        for name, value in (("t0", t), ("t1", t + duration), ("kind", kind), ("p0", p.copy()), ("v0", v.copy()),
                            ("a", accel), ("axis", axis), ("omega", omega)):
            rows[name].append(value)
        if kind == _LINEAR:
            p = p + v * duration + 0.5 * accel * duration**2
            v = v + accel * duration
        else:
            pe, ve, _ = _rotation(p[None], v[None], axis[None], np.array([[omega]]), np.array([[duration]]))
            p, v = pe[0], ve[0]
        t += duration
    return ScriptedTrajectory(
        start_position=np.asarray(start_position, dtype=float), start_velocity=np.asarray(start_velocity, dtype=float),
        legs=legs, piece_t0=np.array(rows["t0"]), piece_t1=np.array(rows["t1"]), piece_kind=np.array(rows["kind"]),
        piece_p0=np.array(rows["p0"]), piece_v0=np.array(rows["v0"]), piece_a=np.array(rows["a"]),
        piece_axis=np.array(rows["axis"]), piece_omega=np.array(rows["omega"]),
    )


def _turn_axis(leg: Leg, v: np.ndarray, index: int) -> np.ndarray:
    if leg.type == "turn":
        axis = np.array([0.0, 0.0, 1.0 if leg.direction == "left" else -1.0])
        if np.hypot(v[0], v[1]) <= 1e-9:
            raise ValueError(f"leg {index}: a horizontal turn needs a horizontal velocity")
        return axis
    side = np.cross(v, [0.0, 0.0, 1.0])
    norm = np.linalg.norm(side)
    if norm <= 1e-9 * np.linalg.norm(v):
        raise ValueError(f"leg {index}: a pull-up needs a velocity that is not vertical")
    side /= norm
    return side if leg.direction == "up" else -side

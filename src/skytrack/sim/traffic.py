"""Random traffic: the ``traffic`` section of a scenario turned into :class:`TargetSpec` objects.

Everything is drawn from the scenario seed (stream ``"traffic"`` of :func:`seed_stream`),
so the same scenario file always holds the same aircraft, whatever Generator later drives
the sensors.  Positions are uniform in area over the region (for an annulus, in the
sensor's own frame); Mode 3/A codes come from an octal range without the special codes
7000/7500/7600/7700, Mode S addresses are distinct random 24-bit numbers.

Landing and departing aircraft: each aircraft lands (a ``land`` leg after its other
manoeuvres), departs (starts low and first climbs to its height drawn from ``alt_m``) or
neither.  These draws come from their own stream (``"airfield"``), so giving a scenario
landing or departing aircraft leaves every other aircraft as it was.
"""

from __future__ import annotations

import numpy as np

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.sim.earth import sensor_relative_positions
from skytrack.sim.spec import (
    RESERVED_MODE3A,
    AccelerateLeg,
    ClimbLeg,
    LandLeg,
    Leg,
    ManeuverSpec,
    SingerLeg,
    StraightLeg,
    TargetSpec,
    TrafficSpec,
    TurnLeg,
)

# a new purpose goes at the end: SeedSequence children are numbered, so the others keep their streams
_STREAMS = ("traffic", "motion", "sensors", "airfield", "carriers", "adsb")


def seed_stream(seed: int, purpose: str) -> np.random.Generator:
    """Independent generator for one purpose (``traffic``, ``motion``, ``sensors``, ``airfield``,
    ``carriers``, ``adsb`` (equipage)) of a scenario seed."""
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(len(_STREAMS))[_STREAMS.index(purpose)])


def generate_traffic(
    spec: TrafficSpec | None, *, seed: int, duration_s: float, sensors: SensorSet, origin: Origin
) -> list[TargetSpec]:
    """The random aircraft of a scenario's ``traffic`` section (deterministic in the scenario ``seed``).

    ``duration_s``, ``sensors`` and ``origin`` are the scenario's (start times stay below the
    duration; an annulus region is placed in the named sensor's frame).
    """
    if spec is None or spec.count == 0:
        return []
    rng = seed_stream(seed, "traffic")
    n = spec.count
    alt = rng.uniform(*spec.alt_m, n)  # the cruise height; departing aircraft start below it
    airfield = seed_stream(seed, "airfield")
    role = airfield.random(n)
    landing = role < spec.landing_fraction
    departing = ~landing & (role < spec.landing_fraction + spec.departure_fraction)
    landing_rate = airfield.uniform(*spec.landing_rate_mps, n)
    start_alt = np.where(departing, airfield.uniform(*spec.departure_alt_m, n), alt)
    climb_rate = airfield.uniform(*spec.maneuvers.climb_rate_mps, n)
    x, y = _positions(spec, sensors, origin, rng, start_alt)
    speed = rng.uniform(*spec.speed_mps, n)
    heading = rng.uniform(*spec.heading_deg, n)
    start = rng.uniform(*spec.start_time_s, n)
    start = np.minimum(start, np.nextafter(duration_s, 0.0))
    transponder = rng.random(n) < spec.transponder_fraction
    has_mode_s = transponder & (rng.random(n) < spec.mode_s_fraction)
    codes = np.full(n, None, dtype=object)
    codes[transponder] = _mode3a_codes(spec, int(transponder.sum()), rng)
    addresses = np.full(n, None, dtype=object)
    addresses[has_mode_s] = _icao24_addresses(int(has_mode_s.sum()), rng)
    maneuvering = rng.random(n) < spec.maneuver_fraction
    width = max(4, len(str(n - 1)))
    targets = []
    for i in range(n):
        legs: tuple[Leg, ...] = (ClimbLeg(float(climb_rate[i]), to_alt_m=float(alt[i])),) if departing[i] else ()
        if maneuvering[i]:
            legs += _random_legs(spec, spec.maneuvers, rng, float(alt[i]))
        if landing[i]:
            legs += (LandLeg(float(landing_rate[i])),)
        targets.append(
            TargetSpec(
                id=f"{spec.id_prefix}{i:0{width}d}",
                x=float(x[i]),
                y=float(y[i]),
                alt_m=float(start_alt[i]),
                speed_mps=float(speed[i]),
                heading_deg=float(heading[i]),
                start_time_s=float(start[i]),
                legs=legs,
                transponder=bool(transponder[i]),
                mode3a=codes[i],
                icao24=addresses[i],
            )
        )
    return targets


def _positions(
    spec: TrafficSpec, sensors: SensorSet, origin: Origin, rng: np.random.Generator, alt: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    region, n = spec.region, spec.count
    if region.type == "rectangle":
        return rng.uniform(*region.x_m, n), rng.uniform(*region.y_m, n)
    ground = np.sqrt(rng.uniform(region.min_range_m**2, region.max_range_m**2, n))
    azimuth = rng.uniform(0.0, 360.0, n)
    return sensor_relative_positions(sensors[region.sensor], origin, ground, azimuth, alt)


def allowed_mode3a_codes(first: str, last: str) -> np.ndarray:
    """Octal codes from ``first`` to ``last`` inclusive without the special codes."""
    codes = [f"{c:04o}" for c in range(int(first, 8), int(last, 8) + 1)]
    return np.array([c for c in codes if c not in RESERVED_MODE3A], dtype=object)


def _mode3a_codes(spec: TrafficSpec, count: int, rng: np.random.Generator) -> np.ndarray:
    pool = allowed_mode3a_codes(*spec.mode3a_range)
    if len(pool) == 0:
        raise ValueError(f"traffic.mode3a_range {list(spec.mode3a_range)} holds no allocatable code")
    if spec.mode3a_allocation == "random":
        return rng.choice(pool, size=count)
    rounds = -(-count // len(pool))  # once the range is used up, codes are handed out again
    return np.concatenate([rng.permutation(pool) for _ in range(max(rounds, 1))])[:count]


def _icao24_addresses(count: int, rng: np.random.Generator) -> list[str]:
    numbers = rng.choice(np.arange(1, 2**24), size=count, replace=False) if count else []
    return [f"{int(a):06x}" for a in numbers]


def _random_legs(spec: TrafficSpec, m: ManeuverSpec, rng: np.random.Generator, alt: float) -> tuple[Leg, ...]:
    kinds = [k for k, _ in m.weights]
    weights = np.array([w for _, w in m.weights], dtype=float)
    weights /= weights.sum()
    legs: list[Leg] = []
    for _ in range(int(rng.integers(m.count[0], m.count[1] + 1))):
        legs.append(StraightLeg(float(rng.uniform(*m.straight_s)) or 1.0))
        kind = kinds[int(rng.choice(len(kinds), p=weights))]
        if kind == "turn":
            direction = "left" if rng.random() < 0.5 else "right"
            legs.append(TurnLeg(float(rng.uniform(*m.turn_g)), direction, turn_deg=float(rng.uniform(*m.turn_deg))))
        elif kind == "climb":
            to_alt = float(rng.uniform(*spec.alt_m))
            if abs(to_alt - alt) < 1.0:
                continue
            legs.append(ClimbLeg(float(rng.uniform(*m.climb_rate_mps)), to_alt_m=to_alt))
            alt = to_alt
        elif kind == "singer":
            legs.append(
                SingerLeg(
                    float(rng.uniform(*m.singer_tau_s)),
                    float(rng.uniform(*m.singer_sigma_a_mps2)),
                    float(rng.uniform(*m.singer_duration_s)),
                    spec.speed_mps,
                )
            )
        else:
            legs.append(AccelerateLeg(float(rng.uniform(*spec.speed_mps)), float(rng.uniform(*m.accelerate_rate_mps2))))
    return tuple(legs)

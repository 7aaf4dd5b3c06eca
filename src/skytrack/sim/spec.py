"""Scenario dataclasses: the validated sections of a scenario file (legs, targets, radar
simulation parameters with their clutter patches, IFF interrogator and airborne carrier,
random traffic, simulated ADS-B), shared by the loader
(:mod:`skytrack.sim.scenario`), the traffic generator (:mod:`skytrack.sim.traffic`), the
trajectories and the radar model.

The keys and their meaning are documented in :mod:`skytrack.sim.scenario`; the whole
scenario (:class:`~skytrack.sim.scenario.Scenario`) lives there too, because it draws its
random traffic with :mod:`skytrack.sim.traffic`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

GRAVITY_MPS2 = 9.80665
SCENARIO_TYPES = ("radar-2d", "radar-3d", "radar-airborne")
#: true IFF status of a target (spec 003 R18): the index is the code of skytrack.core.plots.IFF_VALUES
TARGET_IFF_STATUSES = ("friend", "foe")
LEG_TYPES = ("straight", "turn", "climb", "accelerate", "singer", "waypoints", "land")
RESERVED_MODE3A = ("7000", "7500", "7600", "7700")


@dataclass(frozen=True)
class StraightLeg:
    duration_s: float


@dataclass(frozen=True)
class TurnLeg:
    g: float
    direction: str
    duration_s: float | None = None
    turn_deg: float | None = None


@dataclass(frozen=True)
class ClimbLeg:
    rate_mps: float
    duration_s: float | None = None
    to_alt_m: float | None = None


@dataclass(frozen=True)
class AccelerateLeg:
    to_speed_mps: float
    rate_mps2: float


@dataclass(frozen=True)
class SingerLeg:
    tau_s: float
    sigma_a_mps2: float
    duration_s: float
    speed_range_mps: tuple[float, float] | None = None


@dataclass(frozen=True)
class Waypoint:
    x: float
    y: float
    alt_m: float | None = None


@dataclass(frozen=True)
class WaypointsLeg:
    points: tuple[Waypoint, ...]
    max_g: float


@dataclass(frozen=True)
class LandLeg:
    """Descent at ``rate_mps`` (> 0) along the current heading; the flight ends at touchdown."""

    rate_mps: float
    field_alt_m: float = 0.0


@dataclass(frozen=True)
class AdsbAircraftSpec:
    """ADS-B settings of one aircraft (issue 9, spec 001 input data): a target's ``adsb``
    mapping or an entry of the scenario's ``adsb.aircraft``.

    ``equipped`` None leaves the aircraft to the scenario's ``equipage`` fraction.  The
    faults: ``offset_m`` is a constant ENU (east, north) error of every reported position
    (a faulty navigation source); ``wrong_icao24`` / ``wrong_callsign`` is the identity
    transmitted instead of the true one (True: a derived value of no other aircraft);
    ``no_callsign`` transmits no flight identification."""

    equipped: bool | None = None
    offset_m: tuple[float, float] = (0.0, 0.0)
    wrong_icao24: str | bool | None = None
    wrong_callsign: str | bool | None = None
    no_callsign: bool = False


@dataclass(frozen=True)
class AdsbSpec:
    """The scenario's ``adsb`` section: simulated ADS-B reports of the aircraft (keys in
    :mod:`skytrack.sim.scenario`; the model in :mod:`skytrack.sim.adsb`).

    ``aircraft`` holds the per-aircraft settings given in this section as ``(id, key path,
    settings)``; the ids are checked against the targets when the scenario is simulated
    (random traffic and recorded segments are known only then)."""

    enabled: bool = True
    interval_s: float = 1.0
    jitter_s: float = 0.05
    sigma_m: float = 10.0
    sigma_alt_m: float = 15.0
    velocities: bool = True
    sigma_velocity_mps: float = 1.0
    p_drop: float = 0.0
    outages: tuple[tuple[float, float], ...] = ()
    equipage: float = 1.0
    coverage_m: float | None = None
    aircraft: tuple[tuple[str, str, AdsbAircraftSpec], ...] = ()


Leg = StraightLeg | TurnLeg | ClimbLeg | AccelerateLeg | SingerLeg | WaypointsLeg | LandLeg


@dataclass(frozen=True)
class TargetSpec:
    """Initial state (common ENU frame) and manoeuvres of one simulated aircraft."""

    id: str
    x: float
    y: float
    alt_m: float
    speed_mps: float
    heading_deg: float
    start_time_s: float = 0.0
    legs: tuple[Leg, ...] = ()
    transponder: bool = False
    mode3a: str | None = None
    icao24: str | None = None
    iff: str | None = None
    """true IFF status ("friend" or "foe"); None = no IFF transponder (never replies)"""
    iff_p_reply: float | None = None
    """this target's probability of an IFF reply; None = the radar's ``p_reply``"""
    callsign: str | None = None
    """flight identification (ADS-B); None = derived from the id when the target transmits ADS-B"""
    adsb: AdsbAircraftSpec | None = None
    """this target's ADS-B settings (equipage, faults); None = the scenario's ``adsb`` rules"""


@dataclass(frozen=True)
class ClutterPatch:
    """A region of extra false plots: Poisson(``per_scan``) per revolution, uniform in range and
    azimuth inside it.  ``azimuth_deg`` runs clockwise from low to high and wraps through north
    when low > high ([350, 20] is 30 degrees wide)."""

    range_m: tuple[float, float]
    azimuth_deg: tuple[float, float]
    per_scan: float

    @property
    def width_deg(self) -> float:
        low, high = self.azimuth_deg
        return high - low if high >= low else high - low + 360.0


@dataclass(frozen=True)
class IffSpec:
    """IFF interrogator of a radar (spec 003 R16, R18): reply and error probabilities and the
    simulator's interrogation policy ("always", "never" or closed time windows in seconds)."""

    p_reply: float = 0.9
    p_flip: float = 0.0
    p_code: float = 0.0
    false_reply_p: float = 0.0
    interrogate: str | tuple[tuple[float, float], ...] = "always"


@dataclass(frozen=True)
class RadarSimParams:
    """Simulation-only parameters of one radar (not part of sensors.json)."""

    p_mode3a: float = 1.0
    p_mode_c: float = 1.0
    clutter_elevation_deg: tuple[float, float] = (0.0, 10.0)
    clutter_range_rate_mps: tuple[float, float] = (-300.0, 300.0)
    clutter_distribution: str = "range"
    """"range": false plots uniform in range and azimuth, so dense near the radar, as a real
    radar's are; "area": uniform over the coverage disc"""
    clutter_patches: tuple[ClutterPatch, ...] = ()
    clutter_p_mode3a: float = 0.0
    """probability that a false plot carries a random Mode 3/A code"""
    clutter_p_mode_c: float = 0.0
    """probability that a false plot carries a random Mode C height"""
    iff: IffSpec | None = None
    """IFF interrogator; None = no IFF replies (the plots' iff column stays empty)"""
    carrier: TargetSpec | None = None
    """the flight of a radar-airborne sensor's carrier (same keys and legs as a target)"""
    secondary_only: bool = False
    """an interrogator (secondary surveillance / IFF) without primary radar: only targets that
    reply give plots (``p_detection`` is the reply probability) and the false plots are false
    replies (fruit); see :mod:`skytrack.sim.radar`"""


@dataclass(frozen=True)
class RegionSpec:
    type: str
    sensor: str | None = None
    min_range_m: float = 0.0
    max_range_m: float = 0.0
    x_m: tuple[float, float] = (0.0, 0.0)
    y_m: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class ManeuverSpec:
    count: tuple[int, int] = (1, 3)
    straight_s: tuple[float, float] = (20.0, 120.0)
    weights: tuple[tuple[str, float], ...] = (("turn", 2.0), ("climb", 1.0), ("singer", 1.0), ("accelerate", 0.0))
    turn_g: tuple[float, float] = (1.0, 3.0)
    turn_deg: tuple[float, float] = (30.0, 180.0)
    climb_rate_mps: tuple[float, float] = (5.0, 20.0)
    singer_tau_s: tuple[float, float] = (10.0, 60.0)
    singer_sigma_a_mps2: tuple[float, float] = (2.0, 10.0)
    singer_duration_s: tuple[float, float] = (30.0, 120.0)
    accelerate_rate_mps2: tuple[float, float] = (0.5, 2.0)


@dataclass(frozen=True)
class TrafficSpec:
    count: int
    region: RegionSpec
    alt_m: tuple[float, float]
    speed_mps: tuple[float, float]
    heading_deg: tuple[float, float] = (0.0, 360.0)
    start_time_s: tuple[float, float] = (0.0, 0.0)
    id_prefix: str = "T"
    transponder_fraction: float = 1.0
    mode_s_fraction: float = 0.0
    mode3a_allocation: str = "unique"
    mode3a_range: tuple[str, str] = ("0001", "7777")
    maneuver_fraction: float = 0.0
    maneuvers: ManeuverSpec = field(default_factory=ManeuverSpec)
    landing_fraction: float = 0.0
    landing_rate_mps: tuple[float, float] = (5.0, 10.0)
    departure_fraction: float = 0.0
    departure_alt_m: tuple[float, float] = (200.0, 600.0)

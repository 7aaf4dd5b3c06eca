"""Scenario files of the simulator: YAML (or an equivalent dict) -> validated :class:`Scenario`.

Errors name the document and the key path, e.g.
``scenario.yaml: targets[3].legs[1].g: must be > 0, got -2``; unknown keys are rejected
with the list of the keys allowed at that place; duplicated YAML keys are an error.
Numbers may be written ``250e3`` (plain YAML would read that as a string).

Conventions: SI units, degrees only in keys ending in ``_deg``; the common frame is the
ENU frame at ``origin`` (x east, y north); headings and azimuths are clockwise from
north; ``alt_m`` is the height above the WGS84 ellipsoid; times are seconds since
``epoch_utc``.

Code layout: this module holds :class:`Scenario` and the loader (:func:`load_scenario`);
the section dataclasses (legs, targets, traffic, radar parameters) are in
:mod:`skytrack.sim.spec`, the section parsers in :mod:`skytrack.sim.parse`, and the random
traffic in :mod:`skytrack.sim.traffic`.  All their public names are importable from here.

Key reference
=============

Top level
---------
``name``               text, default: file name without extension
``description``        free text
``origin``             ``{lat, lon, alt_m}`` of the common ENU frame (alt_m default 0)
``epoch_utc``          ISO-8601 UTC time of t = 0 (optional, written to sensors.json)
``duration_s``         simulated time span [0, duration_s]; > 0, required
``seed``               integer >= 0 (default 0).  Trajectories, including random traffic,
                       Singer legs and airborne radars' carriers, depend on the seed only;
                       sensor randomness (detection, noise, clutter, SSR, plot order) comes
                       from the Generator given to ``simulate`` (default: one derived from
                       the same seed), IFF replies from children spawned from it
``truth_sample_s``     truth sampling step, default 1.0
``sensor_defaults``    mapping of sensor keys applied to every sensor that does not set them
``sensors``            list of sensors (at least one)
``targets``            list of scripted targets (optional)
``traffic``            random traffic generator (optional)
``recorded``           recorded aircraft trajectories used as truth (optional, below)
``adsb``               simulated ADS-B reports of the aircraft (optional, below)

Sensors (``sensors[i]``) -- the key names of ``sensors.json`` (FORMATS.md)
----------------------------------------------------------------------
``name``                  unique text, required
``type``                  ``radar-2d`` (default), ``radar-3d`` or ``radar-airborne`` (below)
``lat``, ``lon``          geodetic position, or
``x``, ``y`` [, ``z``]    position in the common ENU frame (m).  Without ``z`` the sensor is at
                          height ``alt_m`` above the ellipsoid; with ``z`` its height follows
                          from z (and ``alt_m``, if given, must agree within 1 m)
``alt_m``                 antenna height above the ellipsoid, default 0
``north_offset_deg``      derived from the position (the sensor's own north); if given it must
                          agree with the derived value within 0.001 deg
``scan_period_s``         antenna revolution period, > 0, required
``scan_phase_s``          time at which the beam points north (default 0); the beam points
                          north at scan_phase_s + k scan_period_s and turns clockwise
``sigma_range_m``         range noise standard deviation >= 0, required
``sigma_azimuth_deg``     azimuth noise standard deviation >= 0, required
``sigma_elevation_deg``   elevation noise, required for radar-3d, optional for radar-airborne
                          (absent: its plots carry no elevation), not allowed for radar-2d
``sigma_range_rate_mps``  range-rate noise; absent/null = the radar measures no range rate
``max_range_m``           instrumented range, > 0, required
``min_elevation_deg``     lowest elevation seen, default 0 (radar-airborne: -90) (in [-90, 90))
``p_detection``           detection probability per beam crossing in coverage, default 1
``clutter_per_scan``      Poisson mean of false plots per scan, default 0
Simulation-only keys (not written to sensors.json):
``p_mode3a``              probability that a plot of a transponder target carries Mode 3/A (default 1)
``p_mode_c``              same for Mode C (default 1)
``clutter_elevation_deg`` [low, high] elevation of false plots of a radar-3d
                          (default [min_elevation_deg, min_elevation_deg + 10]) or of a
                          radar-airborne with sigma_elevation_deg (default [-10, 10])
``clutter_range_rate_mps`` [low, high] range rate of false plots (default [-300, 300])
``clutter_distribution``  ``range`` (default: uniform in range and azimuth, dense near the radar
                          as a real radar's) or ``area`` (uniform over the coverage disc)
``clutter_patches``       list of regions of extra false plots (default none), each
                          ``{range_m: [low, high], azimuth_deg: [from, to], per_scan: mean}``:
                          Poisson(per_scan) false plots per revolution, uniform in range and
                          azimuth inside the patch; the sector runs clockwise from ``from`` to
                          ``to`` (degrees in [0, 360], in the sensor's own frame) and wraps
                          through north when from > to ([350, 20] is 30 deg wide; [0, 360] is
                          all around); range_m within [0, max_range_m], low < high
``clutter_p_mode3a``      probability that a false plot carries a random Mode 3/A code, uniform
                          over 0000-7777 (default 0)
``clutter_p_mode_c``      probability that a false plot carries a random Mode C height, uniform
                          over 0-45 000 ft rounded to 100 ft (default 0)
``iff``                   IFF interrogator of this radar (any type; default none: the plots'
                          ``iff`` column stays empty), below
``secondary_only``        true: the sensor is an interrogator without primary radar (below);
                          default false
Every false plot (coverage-wide or in a patch) comes when the beam crosses its azimuth.

Interrogator (``secondary_only: true``) -- secondary surveillance / IFF without primary radar
---------------------------------------------------------------------------------------------
A radar-2d or radar-3d (not radar-airborne; no ``sigma_range_rate_mps``) that sees only the
aircraft that reply: a target with a transponder (``transponder``, ``mode3a``, ``icao24``), and,
when the sensor has an ``iff`` section, a target with an ``iff`` status.  Its keys keep their
meaning with these readings:
``p_detection``           the probability that a replying aircraft in coverage answers at a beam
                          crossing (the reply probability; the tracker reads it as this
                          sensor's P_D in sensors.json)
``scan_period_s``, ``sigma_range_m``, ``sigma_azimuth_deg``  the interrogator's own (e.g. 5 s,
                          20 m, 0.04 deg: a monopulse SSR)
``clutter_per_scan``, ``clutter_patches``  false replies (fruit) per revolution, default none
``clutter_p_mode3a``, ``clutter_p_mode_c``  probability that a false reply carries a random
                          Mode 3/A code / Mode C height: default 1 here
``p_mode3a``, ``p_mode_c`` as for any radar: the replies' Mode 3/A and Mode C; Mode S
                          addresses are always given; with ``iff`` the plots' ``iff`` and
                          ``mode3a`` come from the IFF replies as for any radar
An interrogator draws from a random stream of its own: adding one to a scenario leaves the
other sensors' plots bit-identical.

Airborne radar (``type: radar-airborne``) -- spec 003 §2.3, R17
----------------------------------------------------------------
The radar flies with its carrier and has no position keys (``lat``, ``lon``, ``x``, ``y``,
``z``, ``alt_m`` are refused) and no ``clutter_patches``.
``carrier``               required: the carrier's flight with a target's keys ``x``/``y`` (or
                          ``lat``/``lon``, or ``range_m``/``azimuth_deg``/``sensor`` of a ground
                          sensor), ``alt_m``, ``speed_mps``, ``heading_deg`` and ``legs`` (any
                          leg but ``land``); it flies from t = 0 and is not a target (no truth
                          rows, no plots)
``scan_period_s``         time between scans: all plots of scan k have the time
                          ``scan_phase_s + k scan_period_s`` (no rotating beam); each scan's
                          plots come in a random order
Plots are measured from the carrier's position and velocity at the plot time, in the
common frame's axes turned by ``north_offset_deg`` (default 0; stabilised angles):
range, azimuth, elevation (with ``sigma_elevation_deg``) and range rate relative to the
carrier (with ``sigma_range_rate_mps``; positive opening).  Coverage: range <=
``max_range_m``, elevation >= ``min_elevation_deg``, the radar horizon of the carrier's and
the target's heights.  The plots carry the carrier's ENU state in the ``platform_x`` ...
``platform_vz`` columns (FORMATS.md) and sensors.json gets type ``radar-airborne``.
``clutter_per_scan`` false plots per scan are uniform in azimuth, in range
(``clutter_distribution``), ``clutter_elevation_deg`` and ``clutter_range_rate_mps``.

IFF interrogator (``sensors[i].iff``) -- spec 003 R16, R18
----------------------------------------------------------
``p_reply``               probability that an interrogated target replies (default 0.9; a
                          target's ``iff_p_reply`` replaces it for that target)
``p_flip``                probability that the replied status is flipped friend <-> foe (default 0)
``p_code``                probability that the replied Mode 3/A code is replaced by one drawn
                          uniformly from the other 4095 codes (default 0)
``false_reply_p``         probability that an interrogated false plot carries a reply, with a
                          random status and code (default 0)
``interrogate``           ``always`` (default), ``never``, or a list of ``[start, end]`` time
                          windows (s, closed): the plots interrogated.  The spec's policy
                          ``track`` (interrogate until the tracker has determined the status)
                          needs the tracker's tracks and is not available in the simulator
An interrogated target with an ``iff`` status replies (:func:`skytrack.sim.iff.respond`):
the plot's ``iff`` column gets the (possibly flipped) status and its ``mode3a`` column the
(possibly corrupted) code of the target's ``mode3a``.  With an interrogator the radar's
Mode 3/A comes from the IFF replies only, so uninterrogated plots carry none; Mode C and
Mode S are unchanged.  The replies draw from a random stream of their own, so adding or
changing ``iff`` leaves every other plot column bit-identical.

Coverage: slant range <= max_range_m, elevation in the sensor's frame >= min_elevation_deg,
and ground distance within the 4/3-Earth radar horizon of sensor and target heights.

Targets (``targets[i]``)
------------------------
``id``             unique text (an integer is turned into text), required
``start_time_s``   time the target appears, in [0, duration_s), default 0
position, one of:  ``x``, ``y`` (common ENU, m) | ``lat``, ``lon`` |
                   ``range_m``, ``azimuth_deg``, ``sensor``: ground range and azimuth in the
                   named sensor's own frame
``alt_m``          height above the ellipsoid, required
``speed_mps``      horizontal speed > 0, required
``heading_deg``    clockwise from the common frame's north, required
``transponder``    true/false; default true when ``mode3a`` or ``icao24`` is given
``mode3a``         Mode 3/A code, a *quoted* string of 4 octal digits ("0100")
``icao24``         Mode S address, 6 hex digits (reported as ``mode_s``); needs a transponder
``iff``            true IFF status, ``friend`` or ``foe``; absent = no IFF transponder (never
                   replies to an interrogator).  The replied code is the target's ``mode3a``
``iff_p_reply``    this target's reply probability (replaces the radar's ``p_reply``); needs ``iff``
``callsign``       flight identification sent by ADS-B, 1-8 letters or digits (upper-cased);
                   default: derived from the id (below)
``adsb``           this target's ADS-B settings (needs the ``adsb`` section; keys below)
``legs``           list of manoeuvres flown one after the other; after the last leg the
                   target flies straight and level until ``duration_s`` or until it has
                   left the coverage of every sensor for good (outside every max range
                   and opening from every sensor)

Legs (``targets[i].legs[j]``), selected by ``type``:
``straight``    ``duration_s`` > 0
``turn``        coordinated turn: ``g`` (lateral acceleration in g, > 0), ``direction``
                ``left`` | ``right``, and exactly one of ``duration_s`` or ``turn_deg`` (> 0).
                Exact circular arc of radius v^2 / (g * 9.80665 m/s^2)
``climb``       ``rate_mps`` (vertical rate, negative = descent) with ``duration_s``, or
                ``rate_mps`` > 0 with ``to_alt_m`` (climbs or descends at that rate)
``accelerate``  ``to_speed_mps`` > 0 reached at ``rate_mps2`` > 0 along the current heading
``singer``      random manoeuvre: ``tau_s`` (manoeuvre time constant), ``sigma_a_mps2``
                (acceleration standard deviation), ``duration_s``; each horizontal axis
                follows the exact Singer model (spec 000, X1-X2) sampled every second,
                cubic-Hermite between samples; the speed is kept within
                ``speed_range_mps`` [low, high] (default [0.7 v, 1.3 v] at the leg start)
``waypoints``   ``points``: list of positions (same position keys as a target, optional
                ``alt_m``, reached linearly along the way), ``max_g`` > 0: each point is
                reached by a coordinated turn at max_g followed by a straight line through
                the point, at constant speed.  A point given by range/azimuth is placed at
                its alt_m or the target's initial altitude
``land``        ``rate_mps`` > 0 (descent rate), ``field_alt_m`` (default 0, below the height
                at the start of the leg): descends straight ahead at that rate and the
                flight ends at touchdown, after (field height - start height) / rate s: no
                truth rows and no plots afterwards.  Must be the last leg.  Aircraft that
                take off: ``start_time_s`` with a low ``alt_m`` (any height is accepted)
                and a ``climb`` leg.  Coverage still applies on the way down or up: a low
                aircraft beyond the radar horizon gives no plots

Traffic (``traffic``) -- random aircraft, all drawn from ``seed``
------------------------------------------------------------------
``count``                 number of aircraft (>= 0), required
``id_prefix``             default ``T`` (ids T0000, T0001, ...)
``region``                ``{type: annulus, sensor, min_range_m, max_range_m}`` (uniform in area
                          around the sensor, in its frame) or ``{type: rectangle, x_m: [lo, hi],
                          y_m: [lo, hi]}`` (common frame)
``alt_m``                 [low, high] initial height, required
``speed_mps``             [low, high], required
``heading_deg``           [low, high], default [0, 360]
``start_time_s``          [low, high], default [0, 0]
``transponder_fraction``  default 1
``mode_s_fraction``       fraction of transponder aircraft with a Mode S address, default 0
``mode3a_allocation``     ``unique`` (distinct codes while the range lasts, then reused; default)
                          or ``random`` (independent draws, duplicates possible)
``mode3a_range``          [first, last] quoted octal codes, default ["0001", "7777"]; the special
                          codes 7000, 7500, 7600 and 7700 are never allocated
``maneuver_fraction``     fraction of aircraft flying random manoeuvres, default 0
``landing_fraction``      fraction of aircraft that land: a ``land`` leg (field height 0) after their
                          other manoeuvres; default 0
``landing_rate_mps``      [low, high] descent rate of the landing aircraft, default [5, 10]
``departure_fraction``    fraction of aircraft that depart: they start at a height uniform in
                          ``departure_alt_m`` and first climb, at a rate uniform in the
                          ``maneuvers`` ``climb_rate_mps``, to their height drawn from ``alt_m``;
                          default 0.  An aircraft lands, departs or neither (the two fractions
                          add up to at most 1); these draws leave the other aircraft unchanged
``departure_alt_m``       [low, high] start height of departing aircraft, default [200, 600];
                          must lie below ``alt_m``
``maneuvers``             how they manoeuvre:
    ``count`` [low, high] manoeuvres per aircraft (default [1, 3]), each preceded by a
    straight leg of ``straight_s`` [low, high] s (default [20, 120]); the kind is drawn with
    ``weights`` {turn, climb, singer, accelerate} (default 2, 1, 1, 0); parameters uniform in
    ``turn_g`` (default [1, 3]), ``turn_deg`` ([30, 180]), ``climb_rate_mps`` ([5, 20]; climbs
    to a height uniform in ``alt_m``), ``singer_tau_s`` ([10, 60]), ``singer_sigma_a_mps2``
    ([2, 10]), ``singer_duration_s`` ([30, 120]), ``accelerate_rate_mps2`` ([0.5, 2]; to a
    speed uniform in ``speed_mps``)

Recorded traffic (``recorded``) -- recorded state vectors as truth
------------------------------------------------------------------
Recorded aircraft (ADS-B / OpenSky state vectors, FORMATS.md "Recorded state vectors") flown
through the same radar model, next to any scripted targets and random traffic.  The recording
is cleaned (:mod:`skytrack.sim.cleaning`), cut into segments at gaps, and each segment is a
target with truth id ``<icao24>-<k>``, Mode S address ``icao24`` and Mode 3/A its squawk,
interpolated by cubic Hermite splines on the recorded velocities
(:mod:`skytrack.sim.recorded_motion`).  The simulator itself does not read the file:
``skytrack simulate`` and :func:`skytrack.app.simulate.run_simulation` do, or pass the
states of :func:`skytrack.io.read_state_vectors` to ``simulate(..., recorded=...)``.
``path``          state-vector file (Parquet, CSV or JSON lines; a relative path is taken from
                  the scenario file's folder), or
``sample``        name of a bundled recording (:func:`skytrack.sim.recorded.bundled_samples`)
``start_utc``     ISO-8601 UTC instant of the recording that becomes time 0, or
``start_s``       seconds after the recording's first time stamp (rounded down to a whole
                  second); default: ``epoch_utc`` when given, else the first time stamp.  Time 0
                  becomes ``epoch_utc`` (sensors.json); ``duration_s`` is the window's length
``altitude``      ``auto`` (default: geometric when the file has it, else barometric),
                  ``geometric`` or ``barometric``: the altitude used as the height above the
                  ellipsoid (barometric without pressure correction)
``adsb``          true (default): also write the recorded samples of the window as ADS-B reports
``adsb_sigma_m``  horizontal noise (m, per axis) added to those reports; default none (as recorded)
``cleaning``      thresholds of :class:`skytrack.sim.cleaning.CleaningOptions`: ``max_gap_s``
                  (60), ``max_speed_mps`` (400), ``position_tolerance_m`` (100),
                  ``max_vertical_rate_mps`` (100), ``altitude_tolerance_m`` (100),
                  ``max_outlier_s`` (300), ``max_short_run_rows`` (3), ``min_interval_s`` (0),
                  ``min_segment_rows`` (2), ``keep_onground`` (false)

ADS-B (``adsb``) -- simulated ADS-B reports (issue 9; model in :mod:`skytrack.sim.adsb`)
---------------------------------------------------------------------------------------
Reports of every equipped aircraft (scripted, random and recorded), made from its truth,
written by ``skytrack simulate`` as ``adsb.<fmt>`` with the true target id as ``truth_id``.
``adsb: true`` is the section with its defaults; ``adsb: false`` (or ``enabled: false``) is
none.  With recorded traffic the section replaces the recorded samples as reports (its
aircraft are then equipped, lost, noisy and faulty like the others; ``recorded.adsb: false``
leaves them unequipped; ``recorded.adsb_sigma_m`` is refused).  Turning ADS-B on or
changing it leaves the radar plots of a seed bit-identical.
``enabled``            true (default) / false
``interval_s``         time between an aircraft's reports, > 0 (default 1); each aircraft has a
                       random phase in [0, interval_s)
``jitter_s``           each report time moves uniformly within +-jitter_s, < interval_s / 2
                       (default 0.05)
``sigma_m``            horizontal position noise, per ENU axis, > 0 (default 10 m); written as
                       the reports' ``sigma_m``
``sigma_alt_m``        height noise >= 0 (default 15 m)
``velocities``         true (default): the reports carry the velocity, with noise
                       ``sigma_velocity_mps`` >= 0 per axis (default 1 m/s); false: none
``p_drop``             probability that a report is lost, independently, in [0, 1] (default 0)
``outages``            list of ``[start, end]`` windows (s, closed) without any report
``equipage``           fraction of the aircraft that transmit, in [0, 1] (default 1): exactly
                       round(equipage x n) of the n aircraft with a transponder and no
                       ``equipped`` setting, drawn from the scenario seed
``coverage_m``         ground-station range: no report from an aircraft farther than this
                       (horizontal distance from the frame's origin; default unlimited)
``equipped``           list of target ids that transmit (whatever the equipage)
``unequipped``         list of target ids that do not
``aircraft``           mapping target id -> settings (the keys below), for random and recorded
                       aircraft; a Mode S address as the key sets every target with it (all
                       segments of a recorded aircraft; quote keys that YAML would read as
                       numbers, "001234").  An id may be set once (in the lists, here or in
                       the target's own ``adsb``)
Per-aircraft settings (``targets[i].adsb`` or ``adsb.aircraft.<id>``):
``equipped``           true / false: transmits or not, whatever the equipage; an aircraft
                       without a transponder transmits only when this is true
``offset_m``           ``[east, north]`` constant error of every reported position (m): a faulty
                       transponder or navigation source; the reports' sigma_m is unchanged
``wrong_icao24``       the address transmitted instead of the true one (6 hex digits), or true
                       for a derived address of no other aircraft
``wrong_callsign``     the callsign transmitted instead (1-8 letters/digits), or true (derived)
``no_callsign``        true: the reports carry no callsign
Identity: the true address is the target's Mode S address (``icao24``; a recorded segment's
icao24), else one derived from its id (SHA-256, distinct from every other address); the
callsign is the target's ``callsign`` (a recorded segment's most frequent one), else the id
in capitals when it is 1-8 letters and digits, else ``SKY`` and five digits.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from skytrack.geo.sensors import Origin, SensorSet
from skytrack.sim._validate import Fields, ScenarioError, load_yaml
from skytrack.sim.adsb import check_target_settings, parse_adsb
from skytrack.sim.earth import sensor_relative_positions
from skytrack.sim.parse import _TARGET_KEYS, _TRAFFIC_KEYS, _Context, _parse_sensors, _parse_target, _parse_traffic
from skytrack.sim.recorded import RECORDED_KEYS, RecordedSpec, parse_recorded
from skytrack.sim.spec import (
    GRAVITY_MPS2,
    AdsbAircraftSpec,
    AdsbSpec,
    LEG_TYPES,
    RESERVED_MODE3A,
    SCENARIO_TYPES,
    AccelerateLeg,
    ClimbLeg,
    ClutterPatch,
    LandLeg,
    Leg,
    ManeuverSpec,
    RadarSimParams,
    RegionSpec,
    SingerLeg,
    StraightLeg,
    TargetSpec,
    TrafficSpec,
    TurnLeg,
    Waypoint,
    WaypointsLeg,
)
from skytrack.sim.traffic import generate_traffic


@dataclass(frozen=True)
class Scenario:
    """A validated scenario: sensors (as :class:`SensorSet`), scripted targets and traffic."""

    name: str
    source: str
    origin: Origin
    duration_s: float
    seed: int
    truth_sample_s: float
    sensors: SensorSet
    radar_params: dict[str, RadarSimParams]
    targets: tuple[TargetSpec, ...] = ()
    traffic: TrafficSpec | None = None
    epoch_utc: str | None = None
    description: str = ""
    recorded: RecordedSpec | None = None
    adsb: AdsbSpec | None = None

    def all_targets(self) -> list[TargetSpec]:
        """Scripted targets followed by the traffic drawn from the seed (ids checked unique)."""
        targets = list(self.targets)
        if self.traffic is not None and self.traffic.count > 0:
            targets += generate_traffic(
                self.traffic, seed=self.seed, duration_s=self.duration_s, sensors=self.sensors, origin=self.origin
            )
        seen: set[str] = set()
        for target in targets:
            if target.id in seen:
                raise ScenarioError(f"{self.source}: target id {target.id!r} is used twice (scripted targets and traffic ids must differ)")
            seen.add(target.id)
        return targets


def scale_traffic(scenario: Scenario, count: int) -> Scenario:
    """The same scenario with ``count`` random aircraft (used by the throughput benchmark)."""
    if scenario.traffic is None:
        raise ScenarioError(f"{scenario.source}: traffic: the scenario has no traffic section to scale")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ValueError(f"traffic count must be an integer >= 0, got {count!r}")
    return dataclasses.replace(scenario, traffic=dataclasses.replace(scenario.traffic, count=int(count)))


# ---------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------

_TOP_KEYS = (
    "name", "description", "origin", "epoch_utc", "duration_s", "seed", "truth_sample_s",
    "sensor_defaults", "sensors", "targets", "traffic", "recorded", "adsb",
)

#: directory of the example scenarios shipped with the package
SCENARIO_DIR = resources.files("skytrack") / "scenarios"


def bundled_scenarios() -> list[str]:
    """Names of the example scenarios shipped with skytrack (``demo``, ``two_radars``, ...)."""
    return sorted(p.name[: -len(".yaml")] for p in SCENARIO_DIR.iterdir() if p.name.endswith(".yaml"))


def bundled_scenario_path(name: str) -> Path:
    """Path of a shipped example scenario by name (``demo`` -> .../scenarios/demo.yaml)."""
    path = SCENARIO_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ScenarioError(f"no bundled scenario named {name!r}; available: {', '.join(bundled_scenarios())}")
    return Path(str(path))


def load_scenario(source: str | Path | dict, overrides: dict | None = None) -> Scenario:
    """Read and validate a scenario from a YAML file, a bundled scenario name or a dict.

    ``overrides`` replaces top-level keys before validation (``{"duration_s": 600}``); a
    mapping given for a mapping key is merged into it, a ``None`` value removing that key
    (``{"recorded": {"start_s": 60, "start_utc": None}}``).
    """
    if isinstance(source, dict):
        return _parse(_override(source, overrides), "scenario", default_name="scenario")
    path = Path(source)
    # a bare name is a bundled scenario unless a file of that name exists here (a folder named
    # "demo" in the working directory does not hide the bundled demo)
    if not path.is_file() and path.suffix == "" and len(path.parts) == 1 and \
            (not path.exists() or str(source) in bundled_scenarios()):
        path = bundled_scenario_path(str(source))
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{source}: cannot read scenario file: {exc.strerror or exc}") from None
    data = _override(load_yaml(text, str(source)), overrides)
    return _parse(data, str(source), default_name=path.stem, base_dir=path.parent)


def _override(data: Any, overrides: dict | None) -> Any:
    """``data`` with the top-level ``overrides`` applied (see :func:`load_scenario`)."""
    if not overrides or not isinstance(data, dict):
        return data
    merged = dict(data)
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            section = {**merged[key], **value}
            merged[key] = {k: v for k, v in section.items() if v is not None}
        elif isinstance(value, dict):
            merged[key] = {k: v for k, v in value.items() if v is not None}
        elif value is None:
            merged.pop(key, None)
        else:
            merged[key] = value
    return merged


def _parse(data: Any, source: str, default_name: str, base_dir: Path | None = None) -> Scenario:
    top = Fields(data, "", source, _TOP_KEYS)
    origin_fields = top.sub("origin", ("lat", "lon", "alt_m"))
    origin = Origin(
        lat=origin_fields.number("lat", ge=-90.0, le=90.0),
        lon=origin_fields.number("lon", ge=-180.0, le=360.0),
        alt_m=origin_fields.number("alt_m", 0.0),
    )
    duration = top.number("duration_s", gt=0.0)
    epoch = top.timestamp("epoch_utc", None)
    sensors, radar_params = _parse_sensors(top, origin, duration)
    sensors.epoch_utc = epoch
    context = _Context(origin, sensors, duration, source)
    targets = tuple(_parse_target(Fields(item, path, source, _TARGET_KEYS), context) for path, item in top.items("targets", None))
    traffic_fields = top.sub("traffic", _TRAFFIC_KEYS, None)
    traffic = None if traffic_fields is None else _parse_traffic(traffic_fields, context)
    recorded = _parse_recorded_section(top, base_dir, epoch)
    adsb = parse_adsb(top)
    _check_adsb(top, adsb, targets, recorded)
    return Scenario(
        name=top.string("name", default_name),
        source=source,
        origin=origin,
        duration_s=duration,
        seed=top.integer("seed", 0, ge=0),
        truth_sample_s=top.number("truth_sample_s", 1.0, gt=0.0),
        sensors=sensors,
        radar_params=radar_params,
        targets=targets,
        traffic=traffic,
        epoch_utc=epoch,
        description=top.string("description", ""),
        recorded=recorded,
        adsb=adsb,
    )


def _check_adsb(top: Fields, adsb: AdsbSpec | None, targets: tuple[TargetSpec, ...], recorded: RecordedSpec | None) -> None:
    """Targets' own ADS-B settings need the section; the section simulates recorded aircraft's reports too."""
    own = {target.id: f"targets[{i}].adsb" for i, target in enumerate(targets) if target.adsb is not None}
    check_target_settings(adsb, own, top.source)
    if adsb is not None and adsb.enabled and recorded is not None and recorded.adsb_sigma_m is not None:
        raise top.error_at(
            "recorded.adsb_sigma_m",
            "the adsb section simulates the ADS-B reports of recorded aircraft too: give their noise as adsb.sigma_m",
        )


def _parse_recorded_section(top: Fields, base_dir: Path | None, epoch: str | None) -> RecordedSpec | None:
    fields = top.sub("recorded", RECORDED_KEYS, None)
    return None if fields is None else parse_recorded(fields, base_dir, epoch)


__all__ = [
    "LEG_TYPES",
    "AdsbAircraftSpec",
    "AdsbSpec",
    "RESERVED_MODE3A",
    "SCENARIO_TYPES",
    "AccelerateLeg",
    "ClimbLeg",
    "ClutterPatch",
    "GRAVITY_MPS2",
    "LandLeg",
    "Leg",
    "ManeuverSpec",
    "RadarSimParams",
    "RecordedSpec",
    "RegionSpec",
    "Scenario",
    "ScenarioError",
    "SingerLeg",
    "StraightLeg",
    "TargetSpec",
    "TrafficSpec",
    "TurnLeg",
    "Waypoint",
    "WaypointsLeg",
    "bundled_scenario_path",
    "bundled_scenarios",
    "load_scenario",
    "scale_traffic",
    "sensor_relative_positions",
]

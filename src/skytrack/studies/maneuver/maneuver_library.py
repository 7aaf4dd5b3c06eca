"""Manoeuvre libraries: prior (expert) data on typical manoeuvres (spec 004 §6 E10 (3), conclusion P12(3)).

A library is a YAML file::

    name: strike                       # optional (default: the file's stem)
    description: free text             # optional
    speed_mps: 250                     # typical speed V (CT rates omega = n g0 / V)
    chain_probability: 0.3             # optional (default 0): a manoeuvre follows the previous one
                                       # without a straight leg in between (weaving)
    ca_sigma_mps2: 8                   # optional: DWPA sigma of the CA mode of non-turn manoeuvres
    maneuvers:
      - {type: turn, load_g: 4, duration_s: 15, per_hour: 40}    # left or right, equally likely
      - {type: accelerate, load_g: 0.5, duration_s: 10, per_hour: 10}
      - {type: pull_up, load_g: 3, duration_s: 5, per_hour: 6}   # up or down, equally likely

``type`` is a leg type of :mod:`skytrack.studies.maneuver.trajectory` (``turn``, ``pull_up``,
``accelerate``); ``load_g`` the typical load factor n (normal acceleration n g0; longitudinal for
``accelerate``); ``duration_s`` its typical duration; ``per_hour`` how often it occurs.

What a library sets (:func:`library_imm`): an IMM (spec 004 §3.3 O) over the m = 3 embedding with
modes CV (DWNA sigma_cv), CT(+omega_i) and CT(-omega_i) for every turn entry with
``omega_i = n_i g0 / V``, and one CA mode (DWPA ``ca_sigma_mps2``) when the library has non-turn
manoeuvres; a fixed Markov matrix Pi for the scan period T (:func:`library_transition`):

* CV: mean sojourn = mean straight time between manoeuvres
  ``tau_cv = (3600 - sum_i f_i d_i) / sum_i f_i`` (f per hour, d in s), ``pi_cv,cv = max(0, 1 - T/tau_cv)``;
  it leaves to manoeuvre mode j with probability proportional to its frequency (a turn's f split
  evenly between its two directions);
* manoeuvre mode j: sojourn = its typical duration d_j (the CA mode: frequency-weighted mean
  duration of its entries), ``pi_jj = max(0, 1 - T/d_j)``; it leaves to CV with probability
  ``1 - chain_probability`` and to the other manoeuvre modes (by frequency) with
  ``chain_probability``.

Scenarios drawn from a library (:func:`draw_case`) follow the same model: a straight lead-in,
then straight legs of exponential length (mean ``tau_cv``, at least ``min_straight_s``)
alternating with manoeuvres drawn by frequency, with load ``n (0.8 .. 1.2)`` and duration
``d (0.7 .. 1.3)`` (uniform factors), and a manoeuvre chained after the previous one with
``chain_probability``; ``accelerate`` manoeuvres push the speed back towards V.  Draws are seeded
(``numpy.random.default_rng(SeedSequence(seed).spawn(draws)[i])``) and rejected when the target
comes closer than ``min_range_m`` to the radar or holds fewer than ``min_maneuvers`` manoeuvres.

Shipped libraries (``libraries/*.yaml`` in this package, :data:`SHIPPED`): ``strike`` (agile
aircraft: 4 g and 7 g turns, jinks, weaving) and ``transport`` (slow, long 1.2 g turns).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from skytrack.filters.imm import IMMFilter, TransitionMatrix
from skytrack.filters.kalman import KalmanFilter
from skytrack.models.embedding import embed
from skytrack.models.polynomial import dwna, dwpa
from skytrack.models.turn import coordinated_turn
from skytrack.studies.maneuver.scenarios import DEFAULT_START_POSITION, Case, SensorSpec, scripted_case
from skytrack.studies.maneuver.trajectory import G0, accelerate, pull_up, straight, turn

LIBRARY_DIR = Path(__file__).with_name("libraries")
SHIPPED = ("strike", "transport")
MANEUVER_TYPES = ("turn", "pull_up", "accelerate")
_ENTRY_KEYS = {"type", "load_g", "duration_s", "per_hour"}
_FILE_KEYS = {"name", "description", "speed_mps", "chain_probability", "ca_sigma_mps2", "maneuvers"}
NDIM = 3


@dataclass(frozen=True)
class ManeuverEntry:
    """One typical manoeuvre: leg type, load factor n, duration (s), frequency (per hour)."""

    type: str
    load_g: float
    duration_s: float
    per_hour: float

    def __post_init__(self) -> None:
        if self.type not in MANEUVER_TYPES:
            raise ValueError(f"maneuver type must be one of {MANEUVER_TYPES}, got {self.type!r}")
        for name in ("load_g", "duration_s", "per_hour"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"maneuver {name} must be a number > 0, got {value!r}")


@dataclass(frozen=True)
class ManeuverLibrary:
    """A manoeuvre library (module docstring)."""

    name: str
    speed_mps: float
    maneuvers: tuple[ManeuverEntry, ...]
    chain_probability: float = 0.0
    ca_sigma_mps2: float = 8.0
    description: str = ""
    sigma_cv: float = field(default=1.0, repr=False)
    sigma_ct: float = field(default=1.0, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speed_mps) and self.speed_mps > 0):
            raise ValueError(f"library {self.name}: speed_mps must be > 0, got {self.speed_mps}")
        if not self.maneuvers:
            raise ValueError(f"library {self.name}: maneuvers must list at least one manoeuvre")
        if not 0.0 <= self.chain_probability < 1.0:
            raise ValueError(f"library {self.name}: chain_probability must be in [0, 1), got {self.chain_probability}")
        if not (math.isfinite(self.ca_sigma_mps2) and self.ca_sigma_mps2 > 0):
            raise ValueError(f"library {self.name}: ca_sigma_mps2 must be > 0, got {self.ca_sigma_mps2}")
        busy = sum(m.per_hour * m.duration_s for m in self.maneuvers)
        if busy >= 3600.0:
            raise ValueError(f"library {self.name}: manoeuvres take {busy:g} s per hour (frequency x duration), "
                             "leaving no straight flight")

    @property
    def rate_per_s(self) -> float:
        return sum(m.per_hour for m in self.maneuvers) / 3600.0

    @property
    def straight_sojourn_s(self) -> float:
        """Mean straight time between manoeuvres, ``(3600 - sum f d) / sum f``."""
        busy = sum(m.per_hour * m.duration_s for m in self.maneuvers)
        return (3600.0 - busy) / sum(m.per_hour for m in self.maneuvers)

    def turn_rate(self, entry: ManeuverEntry) -> float:
        """``omega = n g0 / V`` (rad/s) of a turn entry."""
        return entry.load_g * G0 / self.speed_mps


def parse_library(values: dict, default_name: str) -> ManeuverLibrary:
    """A :class:`ManeuverLibrary` from the YAML mapping of a library file."""
    if not isinstance(values, dict):
        raise ValueError("manoeuvre library: expected a mapping at the top level")
    unknown = sorted(set(values) - _FILE_KEYS)
    if unknown:
        raise ValueError(f"manoeuvre library: unknown key(s) {unknown}; known: {sorted(_FILE_KEYS)}")
    if "speed_mps" not in values:
        raise ValueError("manoeuvre library: speed_mps is required (typical speed for omega = n g0 / V)")
    items = values.get("maneuvers")
    if not isinstance(items, list) or not items:
        raise ValueError("manoeuvre library: maneuvers must be a non-empty list")
    entries = []
    for index, item in enumerate(items):
        if not isinstance(item, dict):
            raise ValueError(f"manoeuvre library: maneuvers[{index}] must be a mapping")
        missing = sorted(_ENTRY_KEYS - set(item))
        extra = sorted(set(item) - _ENTRY_KEYS)
        if missing or extra:
            raise ValueError(f"manoeuvre library: maneuvers[{index}] needs exactly {sorted(_ENTRY_KEYS)}"
                             + (f"; missing {missing}" if missing else "") + (f"; unknown {extra}" if extra else ""))
        try:
            entries.append(ManeuverEntry(str(item["type"]), float(item["load_g"]), float(item["duration_s"]),
                                         float(item["per_hour"])))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"manoeuvre library: maneuvers[{index}]: {exc}") from None
    return ManeuverLibrary(str(values.get("name", default_name)), float(values["speed_mps"]), tuple(entries),
                           float(values.get("chain_probability", 0.0)), float(values.get("ca_sigma_mps2", 8.0)),
                           str(values.get("description", "")))


def load_library(name_or_path: str | Path) -> ManeuverLibrary:
    """A shipped library by name (:data:`SHIPPED`) or a library YAML file."""
    import yaml

    path = LIBRARY_DIR / f"{name_or_path}.yaml" if str(name_or_path) in SHIPPED else Path(name_or_path)
    if not path.is_file():
        raise ValueError(f"manoeuvre library {name_or_path!r}: neither a shipped library ({', '.join(SHIPPED)}) nor a file")
    with open(path, encoding="utf-8") as handle:
        values = yaml.safe_load(handle)
    try:
        return parse_library(values, path.stem)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


# ---------------------------------------------------------------------------- the library-informed IMM
def library_modes(library: ManeuverLibrary) -> list[tuple[str, object, float, float]]:
    """``(name, motion, weight, sojourn_s)`` of the IMM modes; weight = frequency per hour of entering the mode."""
    modes = [("CV", embed(dwna(NDIM, library.sigma_cv), 3), 0.0, library.straight_sojourn_s)]
    for entry in library.maneuvers:
        if entry.type != "turn":
            continue
        omega = library.turn_rate(entry)
        for sign, side in ((1.0, "+"), (-1.0, "-")):
            name = f"CT {side}{math.degrees(omega):.3g} deg/s ({entry.load_g:g} g)"
            modes.append((name, coordinated_turn(NDIM, sign * omega, library.sigma_ct, order=3), entry.per_hour / 2.0,
                          entry.duration_s))
    others = [m for m in library.maneuvers if m.type != "turn"]
    if others:
        frequency = sum(m.per_hour for m in others)
        duration = sum(m.per_hour * m.duration_s for m in others) / frequency
        modes.append((f"CA sigma {library.ca_sigma_mps2:g}", dwpa(NDIM, library.ca_sigma_mps2), frequency, duration))
    return modes


def library_transition(library: ManeuverLibrary, dt: float) -> np.ndarray:
    """Markov matrix ``Pi[M, M]`` of :func:`library_modes` for the scan period ``dt`` (module docstring)."""
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"library transition: dt must be > 0, got {dt}")
    modes = library_modes(library)
    M = len(modes)
    weight = np.array([w for _, _, w, _ in modes])
    stay = np.array([max(0.0, 1.0 - dt / sojourn) for _, _, _, sojourn in modes])
    Pi = np.zeros((M, M))
    Pi[0, 0] = stay[0]
    Pi[0, 1:] = (1.0 - stay[0]) * weight[1:] / weight[1:].sum()
    chain = library.chain_probability if M > 2 else 0.0
    for j in range(1, M):
        Pi[j, j] = stay[j]
        Pi[j, 0] = (1.0 - stay[j]) * (1.0 - chain)
        others = [k for k in range(1, M) if k != j]
        if others and chain > 0:
            w = weight[others]
            Pi[j, others] = (1.0 - stay[j]) * chain * w / w.sum()
    return Pi


def library_imm(library: ManeuverLibrary, dt: float, compiled: bool = True) -> IMMFilter:
    """The library-informed IMM (module docstring) for scans of period ``dt``."""
    modes = library_modes(library)
    return IMMFilter([KalmanFilter(motion, compiled=compiled) for _, motion, _, _ in modes],
                     TransitionMatrix(library_transition(library, dt)), names=tuple(name for name, *_ in modes),
                     compiled=compiled)


# ---------------------------------------------------------------------------- scenarios drawn from a library
@dataclass(frozen=True)
class DrawSettings:
    """How :func:`draw_case` draws a scenario from a library (seconds, metres)."""

    duration_s: float = 300.0
    lead_s: float = 30.0
    tail_s: float = 20.0
    min_straight_s: float = 5.0
    min_range_m: float = 10_000.0
    min_maneuvers: int = 1
    attempts: int = 50


def _legs(library: ManeuverLibrary, rng: np.random.Generator, settings: DrawSettings) -> list:
    entries = library.maneuvers
    p = np.array([m.per_hour for m in entries])
    p = p / p.sum()
    legs, elapsed, speed, chained = [straight(settings.lead_s)], settings.lead_s, library.speed_mps, False
    horizon = settings.duration_s - settings.tail_s
    while elapsed < horizon:
        if not (chained and rng.random() < library.chain_probability):
            gap = max(settings.min_straight_s, rng.exponential(library.straight_sojourn_s))
            gap = min(gap, horizon - elapsed) if horizon - elapsed > settings.min_straight_s else gap
            legs.append(straight(gap))
            elapsed += gap
            if elapsed >= horizon:
                break
        entry = entries[rng.choice(len(entries), p=p)]
        load = entry.load_g * rng.uniform(0.8, 1.2)
        duration = entry.duration_s * rng.uniform(0.7, 1.3)
        if entry.type == "turn":
            legs.append(turn(load, direction="left" if rng.random() < 0.5 else "right", duration_s=duration))
        elif entry.type == "pull_up":
            legs.append(pull_up(load, duration_s=duration, direction="up" if rng.random() < 0.5 else "down"))
        else:
            sign = 1.0 if speed < library.speed_mps else -1.0
            legs.append(accelerate(sign * load, duration))
            speed += sign * load * G0 * duration
        elapsed += duration
        chained = True
    legs.append(straight(settings.tail_s))
    return legs


def draw_case(library: ManeuverLibrary, index: int, seed: int, draws: int, dt: float, sensor: SensorSpec | None = None,
              settings: DrawSettings = DrawSettings()) -> Case:
    """Scenario ``index`` of ``draws`` drawn from ``library`` (module docstring); the label names library and draw."""
    if not 0 <= index < draws:
        raise ValueError(f"draw index must be in [0, {draws}), got {index}")
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)).spawn(int(draws))[index])
    sensor = sensor or SensorSpec()
    start_velocity = (library.speed_mps, 0.0, 0.0)
    for _ in range(settings.attempts):
        legs = _legs(library, rng, settings)
        case = scripted_case(f"library {library.name}", f"{library.name} draw {index + 1}", DEFAULT_START_POSITION,
                             start_velocity, legs, dt, sensor, {"library": library.name, "draw": index + 1})
        distance = np.linalg.norm(case.truth.position - np.asarray(sensor.position), axis=-1)
        if distance.min() >= settings.min_range_m and case.truth.position[:, 2].min() > 100.0 \
                and len(case.maneuvers) >= settings.min_maneuvers:
            return case
    raise ValueError(f"library {library.name}: no draw of {settings.duration_s:g} s had {settings.min_maneuvers} "
                     f"manoeuvre(s) with the target {settings.min_range_m:g} m from the radar and above 100 m "
                     f"in {settings.attempts} attempts")

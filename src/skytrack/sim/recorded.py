"""Recorded traffic as simulation truth: the scenario's ``recorded`` section, the bundled
recordings, and state vectors turned into trajectories and ADS-B reports.

* :class:`RecordedSpec` is the validated ``recorded`` section (keys: see
  :mod:`skytrack.sim.scenario`), :func:`parse_recorded` reads it.
* :func:`bundled_samples` / :func:`sample_path`: the recordings shipped in
  ``skytrack/scenarios/recorded`` (DATA_LICENSE.md at the repository root says where they
  come from and under which terms).
* :func:`prepare_recorded` takes the SI state vectors of
  :func:`skytrack.io.read_state_vectors` (the simulator does not read files: ``io`` sits
  above ``sim``), cleans them (:mod:`skytrack.sim.cleaning`), places the simulated window
  on the recording, interpolates each segment (:mod:`skytrack.sim.recorded_motion`, cubic
  Hermite on the recorded velocities) and builds the ADS-B reports of the window.

Window: scenario time 0 is the instant ``start_utc`` of the recording (or ``start_s``
seconds after its first time stamp, rounded down to a whole second, or the scenario's
``epoch_utc``, or the first time stamp); the scenario's ``duration_s`` is the window's
length, and the window's start becomes the ``epoch_utc`` written to sensors.json.
Every cleaned segment with a sample inside the window is a target whose truth id is its
segment id (``<icao24>-<k>``); Mode S address = ``icao24``; Mode 3/A = the squawk the
segment's samples in the window report most often (one code per target: the radar model
gives a target one code).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.geo.sensors import Origin
from skytrack.geo.wgs84 import geodetic_to_enu
from skytrack.sim._validate import Fields, ScenarioError
from skytrack.sim.cleaning import CleaningOptions, CleaningReport, clean_states
from skytrack.sim.earth import place_at_height
from skytrack.sim.recorded_motion import recorded_velocity, segment_trajectories
from skytrack.sim.trajectories import TrajectorySet

RECORDED_KEYS = ("path", "sample", "start_utc", "start_s", "altitude", "adsb", "adsb_sigma_m", "cleaning")
CLEANING_KEYS = (
    "max_gap_s", "max_speed_mps", "position_tolerance_m", "max_vertical_rate_mps", "altitude_tolerance_m",
    "max_outlier_s", "max_short_run_rows", "min_interval_s", "min_segment_rows", "keep_onground",
)
ALTITUDE_CHOICES = ("auto", "geometric", "barometric")
#: columns of the ADS-B reports built from a recording (FORMATS.md "adsb", plus truth_id)
ADSB_REPORT_COLUMNS = ("time", "icao24", "lat", "lon", "alt_m", "x", "y", "z", "sigma_m", "callsign", "vx", "vy", "vz", "truth_id")

SAMPLE_DIR = resources.files("skytrack") / "scenarios" / "recorded"


def bundled_samples() -> list[str]:
    """Names of the recordings shipped with skytrack (file names without ``.parquet``)."""
    return sorted(p.name[: -len(".parquet")] for p in SAMPLE_DIR.iterdir() if p.name.endswith(".parquet"))


def sample_path(name: str) -> Path:
    """Path of a shipped recording by name."""
    path = SAMPLE_DIR / f"{name}.parquet"
    if not path.is_file():
        raise ScenarioError(f"no bundled recording named {name!r}; available: {', '.join(bundled_samples())}")
    return Path(str(path))


@dataclass(frozen=True)
class RecordedSpec:
    """The ``recorded`` section: which recording, which window, cleaning and ADS-B options."""

    path: Path | None = None
    sample: str | None = None
    start_utc: str | None = None
    start_s: float | None = None
    altitude: str = "auto"
    adsb: bool = True
    adsb_sigma_m: float | None = None
    cleaning: CleaningOptions = dataclasses.field(default_factory=CleaningOptions)

    @property
    def file(self) -> Path | None:
        """The recording's file (the bundled one for ``sample``)."""
        return sample_path(self.sample) if self.sample is not None else self.path


def parse_recorded(fields: Fields, base_dir: Path | None, epoch_utc: str | None) -> RecordedSpec:
    """Validate the ``recorded`` section; a relative ``path`` is taken from ``base_dir``
    (the scenario file's folder), or from the working directory."""
    has_path, has_sample = fields.has("path"), fields.has("sample")
    if has_path == has_sample:
        raise fields.error("path", "give exactly one of path (a state-vector file) or sample (a bundled recording)")
    path = None
    sample = None
    if has_path:
        path = Path(fields.string("path")).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        if not path.is_file():
            raise fields.error("path", f"file not found: {path}")
    else:
        sample = fields.string("sample", choices=tuple(bundled_samples()))
    if fields.has("start_utc") and fields.has("start_s"):
        raise fields.error("start_s", "give at most one of start_utc or start_s")
    start_utc = fields.timestamp("start_utc", None)
    start_s = fields.number("start_s", None, ge=0.0)
    if epoch_utc is not None and start_s is not None:
        raise fields.error("start_s", "the scenario's epoch_utc already places the window: give start_utc or neither")
    if epoch_utc is not None and start_utc is not None and start_utc != epoch_utc:
        raise fields.error(
            "start_utc", f"is {start_utc} but epoch_utc is {epoch_utc}: time 0 of a recorded scenario is the window's start"
        )
    sigma = fields.number("adsb_sigma_m", None, gt=0.0)
    cleaning_fields = fields.sub("cleaning", CLEANING_KEYS, None)
    cleaning = CleaningOptions()
    if cleaning_fields is not None:
        values = {}
        for key in CLEANING_KEYS:
            if not cleaning_fields.has(key):
                continue
            if key == "keep_onground":
                values[key] = cleaning_fields.boolean(key)
            elif key in ("max_short_run_rows", "min_segment_rows"):
                values[key] = cleaning_fields.integer(key, ge=2 if key == "min_segment_rows" else 0)
            elif key in ("max_gap_s", "max_speed_mps", "max_vertical_rate_mps"):
                values[key] = cleaning_fields.number(key, gt=0.0)
            else:
                values[key] = cleaning_fields.number(key, ge=0.0)
        cleaning = CleaningOptions(**values)
    return RecordedSpec(
        path=path,
        sample=sample,
        start_utc=start_utc,
        start_s=start_s,
        altitude=fields.string("altitude", "auto", choices=ALTITUDE_CHOICES),
        adsb=fields.boolean("adsb", True),
        adsb_sigma_m=sigma,
        cleaning=cleaning,
    )


@dataclass
class RecordedTraffic:
    """What :func:`prepare_recorded` made of a recording for one simulated window."""

    trajectories: TrajectorySet
    epoch_utc: str
    window_start_unix_s: float
    cleaning: CleaningReport
    knots: pd.DataFrame  # the cleaned samples used (time in s since epoch_utc), grouped by segment
    callsign: np.ndarray  # [targets] most frequent callsign of each segment, None when absent
    adsb: pd.DataFrame | None


def _iso(unix_s: float) -> str:
    stamp = pd.Timestamp(round(unix_s * 1e6), unit="us", tz="UTC").tz_localize(None)
    return stamp.isoformat() + "Z"


def _window_start(states: pd.DataFrame, spec: RecordedSpec, epoch_utc: str | None) -> float:
    """POSIX seconds of scenario time 0 (module docstring, "Window")."""
    stamp = spec.start_utc or epoch_utc
    if stamp is not None:
        return (pd.Timestamp(stamp) - pd.Timestamp("1970-01-01", tz="UTC")) / pd.Timedelta(seconds=1)
    first = float(np.floor(np.nanmin(states["time"].to_numpy())))
    return first + (spec.start_s or 0.0)


def _window_knots(cleaned: pd.DataFrame, duration_s: float) -> pd.DataFrame:
    """Samples of the segments alive in [0, duration_s], with the one just before and after it."""
    t = cleaned["time"].to_numpy()
    segment = pd.factorize(cleaned["segment_id"])[0]
    same_prev = np.zeros(t.size, dtype=bool)
    same_prev[1:] = segment[1:] == segment[:-1]
    same_next = np.append(same_prev[1:], False)
    inside = (t >= 0.0) & (t <= duration_s)
    next_inside_or_after = np.append(t[1:] >= 0.0, False) & same_next
    prev_inside_or_before = np.append(False, t[:-1] <= duration_s) & same_prev
    keep = inside | ((t < 0.0) & next_inside_or_after) | ((t > duration_s) & prev_inside_or_before)
    # a segment needs a sample inside the window or samples on both sides of it
    kept = cleaned.loc[keep]
    counts = kept.groupby("segment_id", sort=False)["time"].transform("size").to_numpy()
    return kept.loc[counts >= 2].reset_index(drop=True)


def _most_frequent(knots: pd.DataFrame, column: str, window: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Per segment (in ``ids`` order), the most frequent non-null value of ``column`` in the window."""
    rows = knots.loc[window & knots[column].notna().to_numpy(), ["segment_id", column]]
    counts = rows.groupby(["segment_id", column], sort=True).size().rename("n").reset_index()
    best = counts.sort_values(["segment_id", "n"], ascending=[True, False], kind="stable").drop_duplicates("segment_id")
    lookup = dict(zip(best["segment_id"], best[column], strict=True))
    return np.array([lookup.get(i) for i in ids], dtype=object)


def _adsb_reports(knots: pd.DataFrame, window: np.ndarray, origin: Origin, sigma_m: float | None,
                  rng: np.random.Generator) -> pd.DataFrame:
    """The recorded samples inside the window as ADS-B reports (FORMATS.md "adsb")."""
    rows = knots.loc[window].reset_index(drop=True)
    velocity, has = recorded_velocity(rows, origin)
    velocity[~has] = np.nan
    lat, lon, alt = rows["lat"].to_numpy(), rows["lon"].to_numpy(), rows["alt_m"].to_numpy()
    x, y, z = (np.atleast_1d(v) for v in geodetic_to_enu(lat, lon, alt, origin.lat, origin.lon, origin.alt_m))
    if sigma_m is not None:
        # horizontal noise in the common frame, then the point put back at its height
        x = x + sigma_m * rng.standard_normal(x.size)
        y = y + sigma_m * rng.standard_normal(y.size)
        z, lat, lon, _ = place_at_height(x, y, alt, origin)
    return pd.DataFrame(
        {
            "time": rows["time"].to_numpy(dtype=float),
            "icao24": rows["icao24"].astype("str").to_numpy(),
            "lat": lat, "lon": lon, "alt_m": alt, "x": x, "y": y, "z": z,
            "sigma_m": np.full(len(rows), np.nan if sigma_m is None else sigma_m),
            "callsign": rows["callsign"].astype("str").to_numpy(),
            "vx": velocity[:, 0], "vy": velocity[:, 1], "vz": velocity[:, 2],
            "truth_id": rows["segment_id"].astype("str").to_numpy(),
        },
        columns=list(ADSB_REPORT_COLUMNS),
    )


def prepare_recorded(
    states: pd.DataFrame,
    spec: RecordedSpec,
    origin: Origin,
    duration_s: float,
    epoch_utc: str | None,
    rng: np.random.Generator,
    source: str = "recorded",
) -> RecordedTraffic:
    """Clean the state vectors, place the window, interpolate the segments alive in it.

    ``states`` are :func:`skytrack.io.read_state_vectors`' rows; ``rng`` draws the ADS-B
    noise (only with ``adsb_sigma_m``).  Raises :class:`ScenarioError` when no recorded
    aircraft is alive in the window.
    """
    if not np.isfinite(states["time"].to_numpy(dtype=float)).any():
        raise ScenarioError(f"{source}: the recording has no state vector with a time")
    cleaned, report = clean_states(states, spec.cleaning)
    start = _window_start(states, spec, epoch_utc)
    cleaned["time"] = cleaned["time"] - start
    knots = _window_knots(cleaned, duration_s)
    if knots.empty:
        span = (f"{_iso(start + cleaned['time'].min())} to {_iso(start + cleaned['time'].max())}"
                if len(cleaned) else "nothing after cleaning")
        raise ScenarioError(
            f"{source}: no recorded aircraft in the window {_iso(start)} + {duration_s:g} s "
            f"(the cleaned recording covers {span})"
        )
    ids = pd.unique(knots["segment_id"])
    window = ((knots["time"] >= 0.0) & (knots["time"] <= duration_s)).to_numpy()
    # a segment crossing the whole window without a sample inside it still gets its codes
    window_or_all = window | ~knots["segment_id"].isin(knots.loc[window, "segment_id"]).to_numpy()
    icao24 = knots.drop_duplicates("segment_id")["icao24"].astype(str).to_numpy(dtype=object)
    trajectories = segment_trajectories(
        knots, origin, duration_s,
        mode3a=_most_frequent(knots, "squawk", window_or_all, ids),
        icao24=icao24,
    )
    adsb = _adsb_reports(knots, window, origin, spec.adsb_sigma_m, rng) if spec.adsb else None
    return RecordedTraffic(
        trajectories=trajectories,
        epoch_utc=_iso(start),
        window_start_unix_s=start,
        cleaning=report,
        knots=knots,
        callsign=_most_frequent(knots, "callsign", window_or_all, ids),
        adsb=adsb,
    )

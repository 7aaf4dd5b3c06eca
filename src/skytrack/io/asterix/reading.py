"""ASTERIX recordings as tracking input (issue 11 item 1: ``skytrack track FILE.ast`` / ``FILE.pcap``).

:func:`read_asterix_input` reads a ``.ast``/``.asterix`` file (ASTERIX data blocks back to
back: also what a raw dump of UDP payloads is) or a classic libpcap capture (``.pcap``, the
UDP payloads, :mod:`.pcap`), decodes it in one vectorised pass (:func:`decode_asterix`:
CAT048 plots, CAT034 north markers, CAT021 ADS-B reports) and returns what the plots and
ADS-B readers need:

- **sensors by SAC/SIC.** A CAT048 or CAT034 record's I048/010 / I034/010 names its sensor
  through the ``sac``/``sic`` of sensors.json.  An unknown pair is an error naming it and the
  byte offset of its first record, or in lenient mode a counted skip.
- **time.** I048/140, I034/030, I021/071 are times of day (UTC).  Per SAC/SIC the time of
  day is unwrapped over midnight (a step back of more than 12 h is the next day); the day of
  each source's first message is the one that puts that message within 12 h of the epoch
  (sensors.json ``epoch_utc``): ``time = time of day - epoch's time of day + k * 86 400 s``
  with k in {-1, 0, 1}.  So a recording that starts before the epoch's time of day (up to
  12 h) has negative times, and one that starts just after midnight following an epoch late
  in the evening counts from the epoch's date; without an epoch, ``time`` counts from
  midnight of each source's first day (with a warning).
- **units.** The decoder returns the plots layout (``range_m`` = RHO x 1852/256 m,
  ``azimuth_deg`` = THETA x 360/2^16, ``mode_c_ft`` = 25 ft per 1/4 FL).
- **north markers.** CAT034 north markers (I034/000 = 1) give each rotating radar's
  ``scan_phase_s``: the time at which the beam points north, modulo the scan period (their
  circular mean).  They replace the sensor's value in the sensor set (which the tracker
  reads at the radar's first plots), with a warning when sensors.json gave another phase
  (more than 2 % of a scan apart).  Sector crossings are read and not used.
- **damage.** Every decoding problem (bad block length, unknown category, truncated record,
  ...) is an error naming its byte offset in the file (strict) or a counted skip with it
  (lenient).  For a capture the offset is the byte's offset in the ``.pcap`` file;
  packets that are not IPv4/UDP, IP fragments and packets cut short are counted the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from skytrack.geo.sensors import SensorSet
from skytrack.io.asterix import units as u
from skytrack.io.asterix.decode import decode_asterix
from skytrack.io.asterix.pcap import PcapError, udp_payloads
from skytrack.io.checks import parse_epoch
from skytrack.io.errors import InputError, ReadReport

ASTERIX_INPUT_SUFFIXES = (".ast", ".asterix", ".pcap")
#: plots columns kept from the decoder (the plots layout of docs/formats.md, then extras)
PLOT_COLUMNS = ("time", "sensor", "range_m", "azimuth_deg", "mode3a", "mode_c_ft", "mode_s", "sac", "sic",
                "time_of_day_s", "detection_type", "byte_offset")
ADSB_COLUMNS = ("time", "icao24", "lat", "lon", "alt_m", "nacp", "callsign", "vx", "vy", "vz", "sac", "sic",
                "time_of_day_s", "byte_offset")
#: a north-marker phase this far (fraction of a scan) from sensors.json's is worth a warning
PHASE_TOLERANCE = 0.02


def is_asterix_input(path: str | Path) -> bool:
    return str(path).lower().endswith(ASTERIX_INPUT_SUFFIXES)


@dataclass
class AsterixInput:
    """A decoded recording: plots (plots layout, ``time`` in seconds since the epoch), ADS-B
    reports (ADS-B layout), the north-marker phase of each radar that sent markers, and the
    counts of what was read."""

    plots: pd.DataFrame
    adsb: pd.DataFrame
    north_marker_phase_s: dict[str, float] = field(default_factory=dict)
    records: int = 0
    blocks: int = 0


def _fail_or_count(report: ReadReport | None, lenient: bool, file: str, reason: str, count: int,
                   first_offset: int, message: str) -> None:
    error = InputError(message, file=file, where=f"byte offset {first_offset}")
    if not lenient:
        raise error
    report.add_skipped(reason, count, [error])


def seconds_since_epoch(time: np.ndarray, key: np.ndarray, epoch_time_of_day_s: float) -> np.ndarray:
    """``time`` (seconds from midnight of each source's first day, in input order) as seconds
    since the epoch: each source's first message within 12 h of the epoch (module docstring)."""
    out = np.asarray(time, float) - epoch_time_of_day_s
    if out.size == 0:
        return out
    keys, first = np.unique(key, return_index=True)
    days = np.floor((out[first] + u.SECONDS_PER_DAY / 2) / u.SECONDS_PER_DAY)
    return out - u.SECONDS_PER_DAY * days[np.searchsorted(keys, key)]


def north_marker_phase(times: np.ndarray, period_s: float) -> float:
    """Circular mean of the marker times modulo the scan period, in [0, period)."""
    angle = 2 * np.pi * np.asarray(times, float) / period_s
    mean = np.arctan2(np.sin(angle).mean(), np.cos(angle).mean())
    return float(np.mod(mean / (2 * np.pi) * period_s, period_s))


def _decode_file(path: Path, lenient: bool, report: ReadReport | None, *, origin=None, sensor_names=None):
    """Decode a recording; report (or raise on) its problems located in the file; and the map from
    an offset in the decoded bytes to the file's (None for a .ast file)."""
    file = str(path)
    if lenient and report is None:
        raise ValueError("lenient reading needs a ReadReport to count what it skips")
    if not path.exists():
        raise InputError("file not found", file=file)
    raw = path.read_bytes()
    to_file = None
    if file.lower().endswith(".pcap"):
        try:
            capture = udp_payloads(raw)
        except PcapError as exc:
            raise InputError(str(exc), file=file) from None
        for reason, (count, offset) in capture.skipped.items():
            _fail_or_count(report, lenient, file, reason, count, offset, f"{count} capture packet(s): {reason}")
        data, to_file = capture.data, capture.file_offset
    else:
        data = raw
    decoded = decode_asterix(data, sensor_names=sensor_names, origin=origin)
    for problem in decoded.problems.problems:
        offset = problem.offset if to_file is None else int(to_file(problem.offset))
        text = problem.text()  # "byte offset N (block B): kind: ...": the offset goes to the error's location
        _fail_or_count(report, lenient, file, f"ASTERIX {problem.kind}", 1, offset,
                       f"ASTERIX {text[text.index('(block'):]}")
    return decoded, to_file


def _epoch_time_of_day(epoch_utc) -> float | None:
    if epoch_utc is None:
        return None
    epoch = parse_epoch(epoch_utc)
    return float((epoch - epoch.normalize()) / pd.Timedelta(seconds=1))


def _located(columns: dict, to_file) -> dict:
    columns = dict(columns)
    if to_file is not None:
        columns["byte_offset"] = np.asarray(to_file(columns["byte_offset"]), np.int64).reshape(-1)
    return columns


def read_asterix_adsb(path: str | Path, *, origin=None, epoch_utc=None, lenient: bool = False,
                      report: ReadReport | None = None) -> pd.DataFrame:
    """The CAT021 ADS-B reports of a recording in the ADS-B layout (``time`` since ``epoch_utc``
    as for plots; ``vx, vy, vz`` in the ENU frame of ``origin`` when given).  Decoding problems
    are raised or counted as by :func:`read_asterix_input`."""
    decoded, to_file = _decode_file(Path(path), lenient, report, origin=origin)
    adsb = _located(decoded.adsb, to_file)
    epoch_tod = _epoch_time_of_day(epoch_utc)
    if epoch_tod is not None:
        adsb["time"] = seconds_since_epoch(adsb["time"], adsb["sac"] * 256 + adsb["sic"], epoch_tod)
    elif report is not None and adsb["time"].size:
        report.warn("no epoch_utc known: time counts from midnight UTC of each source's first message")
    return pd.DataFrame({name: adsb[name] for name in ADSB_COLUMNS if name in adsb})


def read_asterix_input(path: str | Path, sensors: SensorSet, *, lenient: bool = False,
                       report: ReadReport | None = None) -> AsterixInput:
    """Decode an ASTERIX recording for tracking (module docstring).  Strict mode raises an
    :class:`InputError` naming the byte offset of the first problem; lenient mode counts
    problems in ``report`` (required then) and keeps the rest."""
    path = Path(path)
    file = str(path)
    decoded, to_file = _decode_file(path, lenient, report, origin=sensors.origin, sensor_names=sensors.by_sac_sic())
    problems = decoded.problems
    known = sensors.by_sac_sic()
    if not known and (decoded.plots["range_m"].size or decoded.service["time"].size):
        raise InputError("no sensor of sensors.json has sac/sic: ASTERIX plots are matched to sensors by them "
                         "(add \"sac\": ..., \"sic\": ... to each radar)", file=file)
    epoch_tod = _epoch_time_of_day(sensors.epoch_utc)
    if epoch_tod is None and report is not None:
        report.warn("no epoch_utc in sensors.json: time counts from midnight UTC of each source's first message")
    plots, service = _located(decoded.plots, to_file), _located(decoded.service, to_file)
    listed = ", ".join(f"{name} {sac}/{sic}" for (sac, sic), name in known.items()) or "none"
    for what, columns in (("CAT048 plot", plots), ("CAT034 service message", service)):
        pair = columns["sac"] * 256 + columns["sic"]
        unknown = ~np.isin(pair, [a * 256 + b for a, b in known])
        for value in np.unique(pair[unknown]):
            rows = pair == value
            first = int(columns["byte_offset"][np.flatnonzero(rows)[0]])
            _fail_or_count(report, lenient, file, f"unknown SAC/SIC ({what}s)", int(rows.sum()), first,
                           f"{int(rows.sum())} {what}(s) of SAC/SIC {value >> 8}/{value & 255} (the first at this "
                           f"offset): no sensor of sensors.json has that pair (it has: {listed})")
        for name in list(columns):
            columns[name] = columns[name][~unknown]
    both_time = np.concatenate([plots["time"], service["time"]])
    both_key = np.concatenate([plots["sac"] * 256 + plots["sic"], service["sac"] * 256 + service["sic"]])
    if epoch_tod is not None:
        both_time = seconds_since_epoch(both_time, both_key, epoch_tod)
    plots["time"], service["time"] = both_time[:plots["time"].size], both_time[plots["time"].size:]
    adsb = _located(decoded.adsb, to_file)
    if epoch_tod is not None:
        adsb["time"] = seconds_since_epoch(adsb["time"], adsb["sac"] * 256 + adsb["sic"], epoch_tod)
    phases = _north_marker_phases(service, sensors, report)
    plot_frame = pd.DataFrame({name: plots[name] for name in PLOT_COLUMNS})
    plot_frame = plot_frame.iloc[np.argsort(plot_frame["time"].to_numpy(), kind="stable")].reset_index(drop=True)
    adsb_frame = pd.DataFrame({name: adsb[name] for name in ADSB_COLUMNS if name in adsb})
    return AsterixInput(plots=plot_frame, adsb=adsb_frame, north_marker_phase_s=phases,
                        records=problems.records, blocks=problems.blocks)


def _north_marker_phases(service: dict, sensors: SensorSet, report: ReadReport | None) -> dict[str, float]:
    """Each rotating radar's north-marker phase, set as its ``scan_phase_s`` (module docstring)."""
    phases = {}
    north = service["message_type"] == u.NORTH_MARKER
    for sensor in sensors.sensors:
        mine = north & (service["sensor"] == sensor.name)
        if not mine.any() or not sensor.scan_period_s or sensor.is_moving:
            continue
        period = sensor.scan_period_s
        phase = north_marker_phase(service["time"][mine], period)
        given = sensor.scan_phase_s
        if given is not None and abs((phase - given + period / 2) % period - period / 2) > PHASE_TOLERANCE * period:
            message = (f"sensor {sensor.name!r}: the CAT034 north markers put the beam north at {phase:.3f} s "
                       f"modulo the scan; sensors.json's scan_phase_s {given:g} s is replaced")
            if report is not None:
                report.warn(message)
            else:
                import warnings

                from skytrack.io.errors import InputWarning

                warnings.warn(message, InputWarning, stacklevel=3)
        sensor.scan_phase_s = phase
        phases[sensor.name] = phase
    return phases

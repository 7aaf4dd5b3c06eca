"""``skytrack replay``: send a recording as ASTERIX UDP datagrams paced by its plot times (issue 11 item 3).

:func:`load_recording` reads an ASTERIX file (``.ast``: data blocks as recorded) or a plots table
(``.parquet``/``.csv``, encoded on the fly with :func:`~skytrack.io.asterix.recording.encode_recording`,
blocks small enough for one datagram each).  :func:`datagram_plan` packs whole data blocks into datagrams of at
most ``max_datagram_bytes`` (1 400 by default, under an Ethernet MTU; a recorded block longer than that goes
alone and is counted as oversize: up to 65 507 bytes pass on loopback).  :class:`Replayer` sends each
datagram when its newest record is due: at ``start + (time - first time) / speed`` of wall time.

With ``loop`` the recording is sent again and again, each pass later by the recording's span rounded up to a
whole number of ``loop_period_s`` (the radars' scan period keeps the beam phase the same): the time of day
of every record (I048/140, I034/030) is rewritten in the bytes, so the service sees time go on.

``send_log`` (a path) records, per datagram, its newest record's time of day (unwrapped over midnight and
passes, seconds) and the wall time it was sent, as float64 pairs: the service benchmark measures the latency
of a frame from the send time of its newest plot.
"""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skytrack.io.asterix import units as u
from skytrack.io.asterix.recording import SECTOR_BLOCK_S

DEFAULT_DATAGRAM_BYTES = 1400
#: the largest UDP payload over IPv4
MAX_UDP_PAYLOAD = 65507
#: bytes of the longest CAT048 record :func:`skytrack.io.asterix.recording.encode_recording` writes
MAX_RECORD_BYTES = 19
DAY_RAW = int(u.SECONDS_PER_DAY / u.TIME_LSB_S)


@dataclass
class Recording:
    """ASTERIX data blocks and, per block, its newest record's time of day (unwrapped, s), its record count and
    the byte offsets of every record's time-of-day item (for the time shift of a loop)."""

    data: np.ndarray
    block_starts: np.ndarray
    block_times: np.ndarray
    block_records: np.ndarray
    time_offsets: np.ndarray
    problems: int = 0
    block_plots: np.ndarray | None = None
    """CAT048 records (plots) per block"""

    @property
    def span_s(self) -> float:
        return float(self.block_times.max() - self.block_times.min()) if len(self.block_times) else 0.0

    @property
    def records(self) -> int:
        return int(self.block_records.sum())

    @property
    def plots(self) -> int:
        return int(self.block_plots.sum()) if self.block_plots is not None else self.records


def scan_blocks(data: np.ndarray) -> Recording:
    """The blocks of ASTERIX bytes, their records and times (a compiled scan over all records)."""
    from skytrack.io.asterix.framing import ITEMS_READ, scan_records

    starts = []
    position, size = 0, len(data)
    while position + 3 <= size:
        length = (int(data[position + 1]) << 8) | int(data[position + 2])
        if length < 3 or position + length > size:
            raise ValueError(f"ASTERIX data block at byte {position}: length {length} does not fit the "
                             f"{size}-byte input")
        starts.append(position)
        position += length
    if position != size:
        raise ValueError(f"ASTERIX input: {size - position} bytes after the last block at byte {position}")
    block_starts = np.array(starts, np.int64)
    records, problems, _ = scan_records(data)
    cat = records["cat"]
    columns = {48: ITEMS_READ[48].index("140"), 34: ITEMS_READ[34].index("030")}
    time_at = np.full(cat.size, -1, np.int64)
    for category, column in columns.items():
        time_at = np.where(cat == category, records["items"][:, column], time_at)
    block = np.searchsorted(block_starts, records["start"], side="right") - 1
    has_time = time_at >= 0
    raw = np.zeros(cat.size, np.int64)
    at = time_at[has_time]
    raw[has_time] = (data[at].astype(np.int64) << 16) | (data[at + 1].astype(np.int64) << 8) | data[at + 2]
    seconds = raw * u.TIME_LSB_S
    # unwrap over midnight in record order: a step back of more than half a day is the next day
    steps = np.diff(seconds[has_time])
    days = np.concatenate([[0], np.cumsum((steps < -u.SECONDS_PER_DAY / 2).astype(np.int64)
                                          - (steps > u.SECONDS_PER_DAY / 2))])
    seconds[has_time] = seconds[has_time] + u.SECONDS_PER_DAY * days
    block_times = np.full(len(block_starts), -np.inf)
    np.maximum.at(block_times, block[has_time], seconds[has_time])
    block_times = np.maximum.accumulate(np.where(np.isfinite(block_times), block_times, -np.inf))
    if len(block_times) and not np.isfinite(block_times[0]):
        first = np.flatnonzero(np.isfinite(block_times))
        block_times[: first[0] if first.size else len(block_times)] = block_times[first[0]] if first.size else 0.0
    return Recording(data, block_starts, block_times, np.bincount(block, minlength=len(block_starts)),
                     time_at[has_time], int(len(problems["code"])),
                     np.bincount(block[cat == 48], minlength=len(block_starts)))


def load_recording(path: str | Path, sensors=None, max_datagram_bytes: int = DEFAULT_DATAGRAM_BYTES) -> Recording:
    """An ``.ast`` file as recorded, or a plots table encoded to CAT048 (``sensors``: the sensor set, for the
    SAC/SIC of each sensor and the epoch's time of day)."""
    path = Path(path)
    if path.suffix.lower() in (".ast", ".asterix", ".bin"):
        return scan_blocks(np.fromfile(path, np.uint8))
    if sensors is None:
        raise ValueError(f"{path}: a plots table is encoded to ASTERIX with the sensors' SAC/SIC: give --sensors")
    from skytrack.io import read_plots
    from skytrack.io.asterix.recording import encode_recording
    from skytrack.service.pipeline import sensor_sac_sic, time_of_day_at_epoch

    plots = read_plots(path, sensors)
    records_per_block = max(1, (max_datagram_bytes - 3) // MAX_RECORD_BYTES)
    data = encode_recording(plots, sensor_sac_sic(sensors),
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc),
                            max_records_per_block=records_per_block, block_span_s=SECTOR_BLOCK_S)
    return scan_blocks(np.frombuffer(data, np.uint8))


def datagram_plan(recording: Recording, max_datagram_bytes: int = DEFAULT_DATAGRAM_BYTES,
                  max_span_s: float = SECTOR_BLOCK_S) -> tuple[np.ndarray, np.ndarray]:
    """``(bounds, oversize)``: datagram k holds blocks ``bounds[k]:bounds[k+1]`` (whole blocks, at most
    ``max_datagram_bytes`` unless one block alone is longer: ``oversize`` counts those datagrams), none
    more than ``max_span_s`` of plot time after the datagram's first (a datagram waits for its newest
    plot, so this bounds what pacing adds to the latency of its oldest)."""
    if not 1 <= max_datagram_bytes <= MAX_UDP_PAYLOAD:
        raise ValueError(f"the datagram size must be in 1..{MAX_UDP_PAYLOAD} bytes, got {max_datagram_bytes}")
    ends = np.append(recording.block_starts[1:], len(recording.data))
    lengths = (ends - recording.block_starts).tolist()
    if any(length > MAX_UDP_PAYLOAD for length in lengths):
        raise ValueError(f"an ASTERIX block of {max(lengths)} bytes does not fit one UDP datagram")
    bounds, size, oversize, first_time = [0], 0, 0, 0.0
    times = recording.block_times.tolist()
    for k, length in enumerate(lengths):
        if size and (size + length > max_datagram_bytes or times[k] - first_time > max_span_s):
            bounds.append(k)
            size = 0
        if size == 0:
            first_time = times[k]
        size += length
        if size > max_datagram_bytes:
            oversize += 1
    bounds.append(len(lengths))
    return np.array(bounds, np.int64), np.array(oversize)


def shift_times(recording: Recording, shift_s: float) -> np.ndarray:
    """The recording's bytes with every record's time of day later by ``shift_s`` (modulo a day)."""
    data = recording.data.copy()
    at = recording.time_offsets
    raw = (data[at].astype(np.int64) << 16) | (data[at + 1].astype(np.int64) << 8) | data[at + 2]
    raw = np.mod(raw + int(round(shift_s / u.TIME_LSB_S)), DAY_RAW)
    data[at], data[at + 1], data[at + 2] = (raw >> 16) & 0xFF, (raw >> 8) & 0xFF, raw & 0xFF
    return data


def loop_shift(span_s: float, loop_period_s: float) -> float:
    """How much later each pass of a loop is: the span plus one period, rounded up to whole periods
    (and to the time-of-day LSB, so the shifted bytes keep the plots' spacing exactly)."""
    periods = math.floor(span_s / loop_period_s) + 1
    return round(periods * loop_period_s / u.TIME_LSB_S) * u.TIME_LSB_S


@dataclass
class ReplayReport:
    datagrams: int = 0
    records: int = 0
    plots: int = 0
    bytes: int = 0
    passes: int = 0
    oversize_datagrams: int = 0
    elapsed_s: float = 0.0
    max_behind_s: float = 0.0

    @property
    def records_per_s(self) -> float:
        return self.records / self.elapsed_s if self.elapsed_s > 0 else float("nan")

    @property
    def plots_per_s(self) -> float:
        return self.plots / self.elapsed_s if self.elapsed_s > 0 else float("nan")


class Replayer:
    """Sends a :class:`Recording` to a UDP address at ``speed`` x real time (see the module docstring)."""

    def __init__(self, recording: Recording, address: tuple[str, int], *, speed: float = 1.0, loop: bool = False,
                 loop_period_s: float = 1.0, max_datagram_bytes: int = DEFAULT_DATAGRAM_BYTES,
                 send_log: str | Path | None = None, multicast_ttl: int = 1) -> None:
        if not speed > 0:
            raise ValueError(f"--speed must be > 0, got {speed}")
        if not loop_period_s > 0:
            raise ValueError(f"the loop period must be > 0 s, got {loop_period_s}")
        self.recording = recording
        self.address = address
        self.speed = float(speed)
        self.loop = loop
        self.bounds, oversize = datagram_plan(recording, max_datagram_bytes)
        self.oversize = int(oversize)
        self.shift_s = loop_shift(recording.span_s, loop_period_s)
        self.send_log = None if send_log is None else Path(send_log)
        self.multicast_ttl = multicast_ttl
        self.stopped = False

    def run(self, progress: Callable[[ReplayReport], None] | None = None, duration_s: float | None = None
            ) -> ReplayReport:
        """Send (every pass with ``loop``) until done, :meth:`stop` or ``duration_s`` of wall time."""
        recording, bounds = self.recording, self.bounds
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, self.multicast_ttl)
        with_log = self.send_log is not None
        log = open(self.send_log, "wb") if with_log else None  # noqa: SIM115 (closed in finally)
        report = ReplayReport(oversize_datagrams=self.oversize)
        datagram_times = recording.block_times[np.maximum(bounds[1:] - 1, 0)]
        datagram_records = np.add.reduceat(recording.block_records, bounds[:-1]) if len(bounds) > 1 else np.zeros(0)
        block_plots = recording.block_plots if recording.block_plots is not None else recording.block_records
        datagram_plots = np.add.reduceat(block_plots, bounds[:-1]) if len(bounds) > 1 else np.zeros(0)
        starts = np.append(recording.block_starts, len(recording.data))
        first_time = float(recording.block_times[0]) if len(recording.block_times) else 0.0
        started = time.perf_counter()
        wall_started = time.time()
        next_progress = started + 0.25
        try:
            while not self.stopped:
                shift = report.passes * self.shift_s
                data = recording.data if report.passes == 0 else shift_times(recording, shift)
                payload = data.tobytes()
                pending_log = []
                for k in range(len(bounds) - 1):
                    due = (float(datagram_times[k]) + shift - first_time) / self.speed
                    wait = due - (time.perf_counter() - started)
                    if wait > 0.0005:
                        time.sleep(wait)
                    else:
                        report.max_behind_s = max(report.max_behind_s, -wait)
                    chunk = payload[starts[bounds[k]]:starts[bounds[k + 1]]]
                    sock.sendto(chunk, self.address)
                    now = time.perf_counter()
                    report.datagrams += 1
                    report.records += int(datagram_records[k])
                    report.plots += int(datagram_plots[k])
                    report.bytes += len(chunk)
                    if with_log:
                        pending_log.append((float(datagram_times[k]) + shift, wall_started + (now - started)))
                    if now >= next_progress:
                        report.elapsed_s = now - started
                        if progress is not None:
                            progress(report)
                        if log is not None and pending_log:
                            log.write(np.array(pending_log, np.float64).tobytes())
                            log.flush()
                            pending_log = []
                        next_progress = now + 0.25
                        if duration_s is not None and report.elapsed_s >= duration_s:
                            self.stopped = True
                    if self.stopped:
                        break
                if log is not None and pending_log:
                    log.write(np.array(pending_log, np.float64).tobytes())
                    log.flush()
                report.passes += 1
                if not self.loop:
                    break
        finally:
            sock.close()
            if log is not None:
                log.close()
        report.elapsed_s = time.perf_counter() - started
        if progress is not None:
            progress(report)
        return report

    def stop(self) -> None:
        self.stopped = True


def read_send_log(path: str | Path) -> np.ndarray:
    """``[n, 2]``: (newest record's time of day, unwrapped, s; wall time sent) per datagram."""
    return np.fromfile(path, np.float64).reshape(-1, 2)

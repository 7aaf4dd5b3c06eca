"""The tracking side of ``skytrack serve`` (issue 11 items 3 and 5), free of any network code: ASTERIX
datagrams in, WebSocket frames out.

:class:`LivePipeline` takes batches of datagrams (:meth:`~LivePipeline.ingest`: one vectorised
:func:`~skytrack.io.asterix.decode_asterix` call over the joined datagrams; CAT048 records give plots,
matched to sensors by SAC/SIC, CAT034 records are counted), holds them in the :class:`ReorderBuffer`,
and in :meth:`~LivePipeline.step` feeds the released plots to the :class:`~skytrack.tracker.Tracker`, drains
its output instants, labels them with ADS-B when a :class:`~skytrack.app.identification.TrackLabeler` is
given, and encodes one frame per output instant (:mod:`skytrack.service.frames`).  It counts everything
``/metrics`` reports.  The service runs ``ingest`` + ``step`` in a worker thread, one call at a time.

Plot times: CAT048 carries the time of day (I048/140).  The tracker counts seconds from ``epoch_utc`` of
sensors.json, so a plot's time is its time of day minus the epoch's, plus the whole days that put it
nearest to the newest plot so far (a feed that runs past midnight keeps counting up).
"""

from __future__ import annotations

import time
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from skytrack.core.plots import FT_TO_M, PlotBatch
from skytrack.io.asterix.cat062 import time_of_day_at_epoch  # noqa: F401  (also this module's API)
from skytrack.service.frames import (
    MODE3A_NONE, STATUS_COASTING, STATUS_CONFIRMED, STATUS_IDENTIFIED, encode_frame, mode3a_codes,
)
from skytrack.service.reorder import ReorderBuffer

SECONDS_PER_DAY = 86400.0
#: latency samples kept for the quantiles of /metrics (a ring: memory stays bounded)
LATENCY_SAMPLES = 2048


def sensor_sac_sic(sensors) -> dict[str, tuple[int, int]]:
    """(SAC, SIC) of every radar of a sensor set: the sensor's ``sac``/``sic`` when sensors.json gives them,
    else assigned as a simulated ASTERIX recording assigns them (:func:`skytrack.io.asterix.recording.with_sac_sic`:
    SAC 0, SIC 1, 2, ... in sensor order, skipping pairs already taken), so that replay, serve and
    ``simulate --format asterix`` agree without configuration."""
    from skytrack.io.asterix.recording import with_sac_sic

    _, pairs = with_sac_sic(sensors)
    out = {s.name: pairs[s.name] for s in sensors.sensors if s.is_radar}
    seen: dict[tuple[int, int], str] = {}
    for name, key in out.items():
        if key in seen:
            raise ValueError(f"sensors {seen[key]!r} and {name!r} have the same SAC/SIC {key[0]}/{key[1]}")
        seen[key] = name
    return out


@dataclass
class FrameOut:
    """One output instant, ready to send: the frame, and the labels that changed in it."""

    frame: bytes
    t_s: float
    last_plot_s: float
    n_tracks: int
    changed_labels: dict[int, dict[str, str | None]] = field(default_factory=dict)


class LivePipeline:
    """Datagrams -> plots -> reorder buffer -> tracker -> frames, with the service's counters."""

    def __init__(self, sensors, tracker, window_s: float = 2.0, labeler=None, idle_flush_s: float | None = None,
                 feed_adsb: bool = True):
        self.sensors = sensors
        self.tracker = tracker
        self.labeler = labeler
        #: CAT021 reports of the feed label the tracks (:mod:`skytrack.service.live_adsb`); off when the
        #: labels come from an ADS-B file
        self.live_adsb = None
        if feed_adsb:
            from skytrack.service.live_adsb import LiveAdsb

            self.live_adsb = LiveAdsb(self)
        if labeler is not None:
            tracker.record_assignments()
        self.reorder = ReorderBuffer(len(sensors.sensors), window_s, idle_flush_s)
        resumed_until = tracker.schedule.last_time[np.isfinite(tracker.schedule.last_time)]
        if resumed_until.size:  # a resumed tracker: plots before its last time cannot be taken
            self.reorder.released_until = float(resumed_until.max())
            self.reorder.newest = float(resumed_until.max())
        self.sac_sic = sensor_sac_sic(sensors)
        index = {name: i for i, name in enumerate(sensors.names)}
        self.sensor_of_key = np.full(65536, -1, np.int16)
        for name, (sac, sic) in self.sac_sic.items():
            self.sensor_of_key[sac * 256 + sic] = index[name]
        self.tod_epoch = time_of_day_at_epoch(sensors.epoch_utc)
        self.counters: Counter = Counter()
        self.problems: Counter = Counter()
        self.unknown_sac_sic: Counter = Counter()
        self.latencies: deque[float] = deque(maxlen=LATENCY_SAMPLES)
        self.labels: dict[int, tuple[str | None, str | None]] = {}
        self.sequence = 0
        self.last_plot_s = float("nan")
        self.last_plot_wall = float("nan")
        self.newest_received_wall = float("nan")
        self.tracks_now = 0
        self.rows_fed = 0
        self.tracker_errors: deque[str] = deque(maxlen=20)
        self.confirmed_ids = np.zeros(0, np.int64)
        self._snapshot_confirmed()

    # ------------------------------------------------------------------ input
    def ingest(self, datagrams: list[bytes], received_wall: list[float], now_wall: float | None = None) -> None:
        """Decode a batch of datagrams (one decoder call) and hold their plots in the reorder buffer.

        Every plot of the batch carries the receive time of the batch's first datagram (the decoder
        does not say which datagram a record came from; the latency figures are then upper bounds)."""
        from skytrack.io.asterix import decode_asterix

        if not datagrams:
            return
        now_wall = time.time() if now_wall is None else now_wall
        self.counters["datagrams"] += len(datagrams)
        data = b"".join(datagrams)
        self.counters["bytes"] += len(data)
        decoded = decode_asterix(data)
        for problem in decoded.problems.problems:
            self.problems[problem.kind] += 1
        self.counters["decode_problems"] += len(decoded.problems.problems)
        self.counters["service_messages"] += len(decoded.service["time"])
        adsb = getattr(decoded, "adsb", None) or {}
        self.counters["adsb_reports"] += len(adsb.get("time", ()))
        if self.live_adsb is not None and len(adsb.get("time", ())):
            from skytrack.service.live_adsb import adsb_table

            self.live_adsb.add(adsb_table(adsb, self._tracker_time(adsb["time_of_day_s"]), self.sensors.origin))
        plots = decoded.plots
        n = len(plots["time"])
        self.counters["plots_received"] += n
        if n == 0:
            if not decoded.problems.problems and not len(decoded.service["time"]) and not len(adsb.get("time", ())):
                self.counters["datagrams_without_records"] += len(datagrams)
            return
        key = plots["sac"].astype(np.int64) * 256 + plots["sic"].astype(np.int64)
        sensor = self.sensor_of_key[key]
        unknown = sensor < 0
        if unknown.any():
            self.counters["plots_unknown_sensor"] += int(unknown.sum())
            for k, count in zip(*np.unique(key[unknown], return_counts=True)):
                self.unknown_sac_sic[f"{int(k) >> 8}/{int(k) & 0xFF}"] += int(count)
        known = ~unknown
        batch = PlotBatch(
            time=self._tracker_time(plots["time_of_day_s"][known]),
            sensor=sensor[known],
            range_m=plots["range_m"][known].astype(float),
            azimuth=np.radians(plots["azimuth_deg"][known].astype(float)),
            elevation=np.full(int(known.sum()), np.nan),
            range_rate=np.full(int(known.sum()), np.nan),
            mode_c_m=plots["mode_c_ft"][known].astype(float) * FT_TO_M,
            mode3a=plots["mode3a_code"][known].astype(np.int32),
            mode_s=plots["mode_s_address"][known].astype(np.int32),
            iff=np.full(int(known.sum()), -1, np.int8),
            platform=np.full((int(known.sum()), 6), np.nan),
            row=self.counters["plots_received"] - n + np.flatnonzero(known).astype(np.int64),
        )
        self.counters["plots_late"] += self.reorder.add(batch, received_wall[0], now_wall)
        self.newest_received_wall = received_wall[-1]

    def _tracker_time(self, time_of_day: np.ndarray) -> np.ndarray:
        """Seconds since the epoch of times of day, with the whole days that put them nearest the newest
        plot so far (the first batch: the day of the epoch)."""
        t = np.mod(np.asarray(time_of_day, float) - self.tod_epoch, SECONDS_PER_DAY)
        reference = self.reorder.newest if np.isfinite(self.reorder.newest) else (float(t[0]) if t.size else 0.0)
        return t + SECONDS_PER_DAY * np.round((reference - t) / SECONDS_PER_DAY)

    # ------------------------------------------------------------------ tracking
    def step(self, now_wall: float | None = None) -> list[FrameOut]:
        """Release the plots the reorder window lets go, track them, and return one frame per output
        instant the tracker completed (with the labels that changed)."""
        now_wall = time.time() if now_wall is None else now_wall
        plots, received = self.reorder.release(now_wall)
        if len(plots) == 0:
            return []
        tracker = self.tracker
        tracker.advance_to(float(plots.time.min()))  # the reorder buffer released everything older
        plots.row = self.rows_fed + np.arange(len(plots), dtype=np.int64)
        self.rows_fed += len(plots)
        try:
            tracker.feed(plots, source="udp")
        except ValueError as error:  # bad plots must not stop the service: counted and kept for /health
            self.counters["tracker_errors"] += 1
            self.tracker_errors.append(str(error))
            return []
        self.counters["plots_tracked"] += len(plots)
        self._snapshot_confirmed()
        newest = int(np.argmax(plots.time))
        self.last_plot_s = float(plots.time[newest])
        self.last_plot_wall = float(received[newest])
        return self._frames(now_wall)

    def _frames(self, now_wall: float) -> list[FrameOut]:
        tracker = self.tracker
        table = tracker.drain_arrow()
        tracker.drain_identity_events()  # not sent: the display shows labels, not their history
        taken = tracker.drain_assignments()
        if self.labeler is not None:
            table, _ = self.labeler.label(table, taken)
        if table is None or table.num_rows == 0:
            return []
        columns = {name: table.column(name).to_numpy() for name in
                   ("time", "track_id", "lat", "lon", "alt_m", "vx", "vy", "vz", "n_misses")}
        # text columns as dictionary indices (-1: null): each distinct text is read once, not once per row
        text = {name: _dictionary_indices(table.column(name)) for name in ("mode3a", "icao24", "callsign")}
        ve, vn, vu = local_velocity(columns["vx"], columns["vy"], columns["vz"], columns["lat"], columns["lon"],
                                    self.sensors.origin.lat, self.sensors.origin.lon)
        identified = (text["icao24"][0] >= 0) | (text["callsign"][0] >= 0)
        status = (STATUS_CONFIRMED + STATUS_COASTING * (columns["n_misses"] > 0)
                  + STATUS_IDENTIFIED * identified).astype(np.uint8)
        mode3a_index, mode3a_texts = text["mode3a"]
        codes = np.append(mode3a_codes(mode3a_texts), MODE3A_NONE).astype(np.uint16)[mode3a_index]
        callsign = _texts(*text["callsign"])
        icao24 = _texts(*text["icao24"])
        times = columns["time"]
        starts = np.flatnonzero(np.concatenate([[True], times[1:] != times[:-1]]))
        bounds = np.append(starts, len(times))
        frames = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            rows = slice(a, b)
            frame = encode_frame(
                track_id=columns["track_id"][rows], lat_deg=columns["lat"][rows], lon_deg=columns["lon"][rows],
                alt_m=columns["alt_m"][rows], ve_mps=ve[rows], vn_mps=vn[rows], vu_mps=vu[rows],
                mode3a=codes[rows], status=status[rows], t_s=float(times[a]), last_plot_s=self.last_plot_s,
                sequence=self.sequence & 0xFFFFFFFF, sent_unix_s=now_wall)
            self.sequence += 1
            changed = self._changed_labels(columns["track_id"][rows], callsign[rows], icao24[rows], identified[rows])
            frames.append(FrameOut(frame, float(times[a]), self.last_plot_s, int(b - a), changed))
        self.tracks_now = frames[-1].n_tracks
        if len(self.labels) > 2 * max(self.tracks_now, 64):  # labels of ended tracks: forgotten (bounded memory)
            self.forget_labels(columns["track_id"][starts[-1]:])
        self.counters["frames_built"] += len(frames)
        self.counters["output_instants"] += len(frames)
        return frames

    def _changed_labels(self, track_id, callsign, icao24, identified) -> dict[int, dict[str, str | None]]:
        changed = {}
        for k in np.flatnonzero(identified):  # labelled tracks only: few, and labels rarely change
            key, label = int(track_id[k]), (callsign[k], icao24[k])
            if self.labels.get(key) != label:
                self.labels[key] = label
                changed[key] = {"callsign": label[0], "icao24": label[1]}
        return changed

    def forget_labels(self, alive_ids: np.ndarray) -> None:
        """Drop the labels of tracks no longer in the picture (the label table stays bounded)."""
        alive = set(int(i) for i in alive_ids)
        for key in [k for k in self.labels if k not in alive]:
            del self.labels[key]

    def record_latency(self, sent_wall: float) -> None:
        """A frame left at ``sent_wall``: its newest plot's receive-to-send latency joins the quantiles."""
        if np.isfinite(self.last_plot_wall):
            self.latencies.append(sent_wall - self.last_plot_wall)

    def latency_quantiles(self, quantiles=(0.5, 0.9, 0.99)) -> dict[float, float]:
        if not self.latencies:
            return {q: float("nan") for q in quantiles}
        values = np.quantile(np.fromiter(self.latencies, float), quantiles)
        return dict(zip(quantiles, (float(v) for v in values)))

    @property
    def confirmed_tracks(self) -> int:
        return len(self.confirmed_ids)

    def confirmed_track_ids(self) -> np.ndarray:
        """Ids of the tracker's confirmed tracks (coasting ones included) after the last step: a copy
        taken in the tracking thread, so the event loop can read it while the next step runs."""
        return self.confirmed_ids

    def _snapshot_confirmed(self) -> None:
        from skytrack.tracker.bank import CONFIRMED

        bank = self.tracker.bank
        self.confirmed_ids = np.array(bank.track_id[bank.status == CONFIRMED], dtype=np.int64)


def _dictionary_indices(column) -> tuple[np.ndarray, list]:
    """An Arrow text column as (indices into its distinct values, -1 for null; the distinct values)."""
    import pyarrow as pa

    array = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    if not pa.types.is_dictionary(array.type):
        array = array.dictionary_encode()
    indices = array.indices.fill_null(-1).to_numpy(zero_copy_only=False).astype(np.int64)
    return indices, array.dictionary.to_pylist()


def _texts(indices: np.ndarray, values: list) -> np.ndarray:
    """Object array of the texts (None for null) of dictionary indices."""
    return np.append(np.array(values, dtype=object), None)[indices]


def local_velocity(vx, vy, vz, lat_deg, lon_deg, origin_lat_deg: float, origin_lon_deg: float):
    """Velocities in the common ENU frame (the origin's) turned into each track's own east/north/up
    (a track far from the origin has its north rotated); ``vz`` NaN (2-D tracks) is taken as 0 for the
    turn and ``vu`` is NaN then."""
    def axes(lat, lon):
        sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
        east = np.stack([-so, co, np.zeros_like(so)], -1)
        north = np.stack([-sl * co, -sl * so, cl], -1)
        up = np.stack([cl * co, cl * so, sl], -1)
        return east, north, up

    e0, n0, u0 = axes(np.radians(np.array(origin_lat_deg)), np.radians(np.array(origin_lon_deg)))
    vz0 = np.nan_to_num(vz)
    ecef = vx[:, None] * e0 + vy[:, None] * n0 + vz0[:, None] * u0
    e, n, u = axes(np.radians(lat_deg), np.radians(lon_deg))
    ve, vn, vu = (np.einsum("ij,ij->i", ecef, axis) for axis in (e, n, u))
    return ve, vn, np.where(np.isnan(vz), np.nan, vu)

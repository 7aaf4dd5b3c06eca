"""The WebSocket protocol of ``skytrack serve`` (issue 11 item 3): the messages the service sends to a browser.

Endpoint ``/ws``.  On connect the server sends one TEXT message, :func:`hello_message` (epoch, origin,
sensors, trail length), then the labels of every labelled track (:func:`labels_message`), then at every
output instant one BINARY frame, :func:`encode_frame`, little-endian:

header, 40 bytes (:data:`HEADER`)::

    0  4 bytes  magic b"SKT1"
    4  u32      n            tracks in this frame (the full picture, not a diff)
    8  f64      t_s          picture time, seconds since epoch_utc
   16  f64      last_plot_s  time of the newest plot the tracker has processed (latency measurement)
   24  u32      sequence     frame counter from 0
   28  u32      flags        0 (reserved)
   32  f64      sent_unix_s  wall clock (time.time()) when the server sent the frame

then the columns of :data:`COLUMNS`, n values each, in this order, the 4-byte columns first so that
every column starts at an offset that is a multiple of its item size (a browser can take a typed-array
view of each without copying)::

    track_id u32 | lat_deg f32 | lon_deg f32 | alt_m f32 (NaN: no height) | ve_mps f32 | vn_mps f32 |
    vu_mps f32 | mode3a u16 (Mode 3/A code as the integer of its 4 octal digits, 0..4095; 0xFFFF none) |
    status u8 (bit0 confirmed, bit1 coasting, bit2 identified)

The columns take 7 x 4 + 2 + 1 = 31 bytes per track, so a frame is ``40 + 31 n`` bytes long
(:func:`frame_length`).  (The issue-11 briefing's "40 + 30 n" miscounts its own column list; the
column list is the contract, and this module's :data:`BYTES_PER_TRACK` is computed from it.)

A TEXT message ``{"type": "labels", "labels": {"<track_id>": {"callsign": ..., "icao24": ...}}}`` carries
track labels (on connect, then on change only); ``{"type": "status", ...}`` carries service counters.
:func:`decode_frame` reads a frame back (tests, benchmarks, the latency client).
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Mapping, Sequence

import numpy as np

from skytrack.geo.wgs84 import enu_to_geodetic

MAGIC = b"SKT1"
#: the frame header: magic, n, t_s, last_plot_s, sequence, flags, sent_unix_s (little-endian, no padding)
HEADER = struct.Struct("<4sIddIId")
HEADER_BYTES = HEADER.size
#: (name, little-endian dtype) of the columns, in wire order
COLUMNS: tuple[tuple[str, str], ...] = (
    ("track_id", "<u4"), ("lat_deg", "<f4"), ("lon_deg", "<f4"), ("alt_m", "<f4"),
    ("ve_mps", "<f4"), ("vn_mps", "<f4"), ("vu_mps", "<f4"), ("mode3a", "<u2"), ("status", "u1"),
)
BYTES_PER_TRACK = sum(np.dtype(dtype).itemsize for _, dtype in COLUMNS)
#: mode3a value of a track without a Mode 3/A code
MODE3A_NONE = 0xFFFF
STATUS_CONFIRMED = 1
STATUS_COASTING = 2
STATUS_IDENTIFIED = 4
#: seconds of trail the display keeps per track (sent in the hello message)
DEFAULT_TRAIL_S = 120.0

assert HEADER_BYTES == 40, HEADER_BYTES


def frame_length(n: int) -> int:
    """Bytes of a frame with ``n`` tracks."""
    return HEADER_BYTES + BYTES_PER_TRACK * n


def encode_frame(*, track_id, lat_deg, lon_deg, alt_m, ve_mps, vn_mps, vu_mps, mode3a, status,
                 t_s: float, last_plot_s: float, sequence: int, sent_unix_s: float | None = None,
                 flags: int = 0) -> bytes:
    """One binary frame of ``n`` tracks: column arrays (any numeric dtype, length n each) cast to the
    wire types and concatenated after the header; ``sent_unix_s`` defaults to ``time.time()`` now.

    ``mode3a`` holds the integer of the 4 octal digits (0..4095) or :data:`MODE3A_NONE`
    (:func:`mode3a_codes` converts text codes); ``status`` the bit set of ``STATUS_*``.
    """
    values = {"track_id": track_id, "lat_deg": lat_deg, "lon_deg": lon_deg, "alt_m": alt_m, "ve_mps": ve_mps,
              "vn_mps": vn_mps, "vu_mps": vu_mps, "mode3a": mode3a, "status": status}
    arrays = [np.asarray(values[name]) for name, _ in COLUMNS]
    n = len(arrays[0])
    for (name, _), array in zip(COLUMNS, arrays):
        if array.shape != (n,):
            raise ValueError(f"frame column {name!r} has shape {array.shape}, expected ({n},) like track_id")
    track_ids = arrays[0]
    if n and (track_ids.min() < 0 or track_ids.max() > 0xFFFFFFFF):
        raise ValueError(f"track_id out of u32 range: {track_ids.min()}..{track_ids.max()}")
    codes = arrays[7]
    if n and ((codes < 0) | ((codes > 0o7777) & (codes != MODE3A_NONE))).any():
        bad = int(np.flatnonzero((codes < 0) | ((codes > 0o7777) & (codes != MODE3A_NONE)))[0])
        raise ValueError(f"mode3a of track {int(track_ids[bad])} (row {bad}) is {codes[bad]}: not 0..4095 nor 0xFFFF")
    if sequence < 0 or sequence > 0xFFFFFFFF:
        raise ValueError(f"sequence out of u32 range: {sequence}")
    header = HEADER.pack(MAGIC, n, float(t_s), float(last_plot_s), int(sequence) & 0xFFFFFFFF, int(flags),
                         time.time() if sent_unix_s is None else float(sent_unix_s))
    body = b"".join(array.astype(dtype, copy=False).tobytes() for array, (_, dtype) in zip(arrays, COLUMNS))
    return header + body


def stamp_sent_time(frame: bytes, sent_unix_s: float | None = None) -> bytes:
    """The frame with its ``sent_unix_s`` header field set (now by default): a frame encoded once can be
    stamped at the moment it goes out."""
    stamp = struct.pack("<d", time.time() if sent_unix_s is None else sent_unix_s)
    return frame[:32] + stamp + frame[40:]


def decode_frame(frame: bytes | bytearray | memoryview) -> dict[str, object]:
    """A binary frame read back: the header fields (``n``, ``t_s``, ``last_plot_s``, ``sequence``,
    ``flags``, ``sent_unix_s``) and one numpy array per column (views into ``frame``)."""
    buffer = memoryview(frame).cast("B")
    if len(buffer) < HEADER_BYTES:
        raise ValueError(f"frame of {len(buffer)} bytes is shorter than the {HEADER_BYTES}-byte header")
    magic, n, t_s, last_plot_s, sequence, flags, sent_unix_s = HEADER.unpack_from(buffer, 0)
    if magic != MAGIC:
        raise ValueError(f"frame magic at byte 0 is {bytes(magic)!r}, expected {MAGIC!r}")
    if len(buffer) != frame_length(n):
        raise ValueError(f"frame of {len(buffer)} bytes announces {n} tracks: expected {frame_length(n)} bytes")
    out: dict[str, object] = {"n": n, "t_s": t_s, "last_plot_s": last_plot_s, "sequence": sequence, "flags": flags,
                              "sent_unix_s": sent_unix_s}
    offset = HEADER_BYTES
    for name, dtype in COLUMNS:
        out[name] = np.frombuffer(buffer, dtype=dtype, count=n, offset=offset)
        offset += np.dtype(dtype).itemsize * n
    return out


def column_offsets(n: int) -> dict[str, int]:
    """Byte offset of each column in a frame of ``n`` tracks (the browser decoder's views)."""
    offsets, offset = {}, HEADER_BYTES
    for name, dtype in COLUMNS:
        offsets[name] = offset
        offset += np.dtype(dtype).itemsize * n
    return offsets


#: the wire integer of every valid Mode 3/A text
_MODE3A_OF_TEXT = {f"{code:04o}": code for code in range(4096)}


def mode3a_codes(texts: Sequence[object] | np.ndarray) -> np.ndarray:
    """Mode 3/A texts of 4 octal digits (``"7500"``) to the wire integers; missing or malformed texts
    (None, NaN, "", "12a4") give :data:`MODE3A_NONE`."""
    lookup = _MODE3A_OF_TEXT.get
    return np.fromiter((lookup(text, MODE3A_NONE) if isinstance(text, str) else MODE3A_NONE for text in texts),
                       dtype=np.uint16, count=len(texts))


def hello_message(sensors, trail_s: float = DEFAULT_TRAIL_S) -> str:
    """The hello TEXT message for a :class:`~skytrack.geo.sensors.SensorSet`: epoch, origin, sensors."""
    origin = sensors.origin
    return json.dumps({
        "type": "hello",
        "epoch_utc": sensors.epoch_utc,
        "origin": {"lat": origin.lat, "lon": origin.lon, "alt_m": origin.alt_m},
        "sensors": [{"name": s.name, "type": s.type, **_sensor_lat_lon(s, origin), "max_range_m": s.max_range_m}
                    for s in sensors.sensors],
        "trail_s": trail_s,
    })


def _sensor_lat_lon(sensor, origin) -> dict[str, float | None]:
    """A sensor's lat/lon as given, else from its ENU position (a sensor placed by x/y); None for a moving one."""
    if sensor.lat is not None and sensor.lon is not None:
        return {"lat": float(sensor.lat), "lon": float(sensor.lon)}
    if sensor.is_moving or sensor.type == "adsb":
        return {"lat": None, "lon": None}
    lat, lon, _ = enu_to_geodetic(*sensor.position, origin.lat, origin.lon, origin.alt_m)
    return {"lat": float(lat), "lon": float(lon)}


def labels_message(labels: Mapping[int, Mapping[str, str | None]]) -> str:
    """The labels TEXT message: ``{track_id: {"callsign": ..., "icao24": ...}}`` (keys become strings)."""
    return json.dumps({"type": "labels", "labels": {
        str(int(track_id)): {"callsign": label.get("callsign"), "icao24": label.get("icao24")}
        for track_id, label in labels.items()}})


def status_message(counters: Mapping[str, object]) -> str:
    """The status TEXT message with the service counters (plots/s, late plots, clients...)."""
    return json.dumps({"type": "status", **counters})

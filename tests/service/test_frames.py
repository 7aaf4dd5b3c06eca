"""The service's WebSocket protocol (skytrack.service.frames): frames round trip, length, alignment, codes."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.service.frames import (
    BYTES_PER_TRACK, COLUMNS, HEADER_BYTES, MODE3A_NONE, STATUS_COASTING, STATUS_CONFIRMED, STATUS_IDENTIFIED,
    column_offsets, decode_frame, encode_frame, frame_length, hello_message, labels_message, mode3a_codes,
    stamp_sent_time,
)


def _columns(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "track_id": rng.integers(1, 2**32 - 1, n, dtype=np.int64),
        "lat_deg": rng.uniform(-90, 90, n), "lon_deg": rng.uniform(-180, 180, n),
        "alt_m": np.where(rng.random(n) < 0.3, np.nan, rng.uniform(0, 12000, n)),
        "ve_mps": rng.normal(0, 200, n), "vn_mps": rng.normal(0, 200, n), "vu_mps": rng.normal(0, 10, n),
        "mode3a": np.where(rng.random(n) < 0.2, MODE3A_NONE, rng.integers(0, 4096, n)),
        "status": rng.integers(0, 8, n),
    }


@pytest.mark.parametrize("n", [0, 1, 7, 1000])
def test_round_trip_and_length(n):
    cols = _columns(n)
    frame = encode_frame(**cols, t_s=3600.25, last_plot_s=3599.875, sequence=42, sent_unix_s=1.7e9 + 0.5)
    assert len(frame) == 40 + 31 * n == frame_length(n)
    out = decode_frame(frame)
    assert (out["n"], out["t_s"], out["last_plot_s"], out["sequence"], out["flags"], out["sent_unix_s"]) == (
        n, 3600.25, 3599.875, 42, 0, 1.7e9 + 0.5)
    np.testing.assert_array_equal(out["track_id"], cols["track_id"])
    for name in ("lat_deg", "lon_deg", "alt_m", "ve_mps", "vn_mps", "vu_mps"):
        # f32 on the wire: equal to the float32 rounding of the input, NaN kept
        np.testing.assert_array_equal(out[name], cols[name].astype(np.float32))
    np.testing.assert_array_equal(out["mode3a"], cols["mode3a"])
    np.testing.assert_array_equal(out["status"], cols["status"])


def test_header_layout_is_the_documented_bytes():
    frame = encode_frame(**_columns(3), t_s=1.5, last_plot_s=-2.25, sequence=7, sent_unix_s=10.0)
    assert frame[:4] == b"SKT1"
    assert struct.unpack_from("<I", frame, 4)[0] == 3
    assert struct.unpack_from("<d", frame, 8)[0] == 1.5
    assert struct.unpack_from("<d", frame, 16)[0] == -2.25
    assert struct.unpack_from("<I", frame, 24)[0] == 7
    assert struct.unpack_from("<I", frame, 28)[0] == 0
    assert struct.unpack_from("<d", frame, 32)[0] == 10.0
    assert HEADER_BYTES == 40 and BYTES_PER_TRACK == 31


@pytest.mark.parametrize("n", [1, 2, 3, 5, 333])
def test_every_column_is_aligned_to_its_item_size(n):
    offsets = column_offsets(n)
    names = [name for name, _ in COLUMNS]
    assert names == ["track_id", "lat_deg", "lon_deg", "alt_m", "ve_mps", "vn_mps", "vu_mps", "mode3a", "status"]
    for name, dtype in COLUMNS:
        assert offsets[name] % np.dtype(dtype).itemsize == 0, name
    assert offsets["lat_deg"] == 40 + 4 * n and offsets["mode3a"] == 40 + 28 * n and offsets["status"] == 40 + 30 * n
    frame = encode_frame(**_columns(n), t_s=0.0, last_plot_s=0.0, sequence=0)
    assert frame[offsets["status"]:] == np.asarray(_columns(n)["status"], np.uint8).tobytes()


def test_mode3a_and_status_encoding():
    codes = mode3a_codes(["7500", "0000", "7777", None, "", "1238", "12345", np.nan, "0017"])
    np.testing.assert_array_equal(codes, [0o7500, 0, 4095, MODE3A_NONE, MODE3A_NONE, MODE3A_NONE, MODE3A_NONE,
                                          MODE3A_NONE, 15])
    assert codes.dtype == np.uint16
    status = np.array([STATUS_CONFIRMED, STATUS_CONFIRMED | STATUS_COASTING,
                       STATUS_CONFIRMED | STATUS_IDENTIFIED, 0])
    frame = encode_frame(track_id=[1, 2, 3, 4], lat_deg=[0] * 4, lon_deg=[0] * 4, alt_m=[0] * 4, ve_mps=[0] * 4,
                         vn_mps=[0] * 4, vu_mps=[0] * 4, mode3a=[0o7500, 0, 4095, MODE3A_NONE], status=status,
                         t_s=0, last_plot_s=0, sequence=0)
    out = decode_frame(frame)
    assert out["mode3a"].tolist() == [3904, 0, 4095, 65535]
    assert out["status"].tolist() == [1, 3, 5, 0]
    # the bytes of the mode3a column: u16 little-endian
    assert frame[40 + 28 * 4: 40 + 28 * 4 + 2] == bytes([3904 & 0xFF, 3904 >> 8])


def test_bad_input_is_named():
    cols = _columns(3)
    with pytest.raises(ValueError, match=r"mode3a of track .* \(row 1\) is 4096"):
        encode_frame(**{**cols, "mode3a": np.array([1, 4096, 2])}, t_s=0, last_plot_s=0, sequence=0)
    with pytest.raises(ValueError, match="column 'lat_deg' has shape"):
        encode_frame(**{**cols, "lat_deg": np.zeros(2)}, t_s=0, last_plot_s=0, sequence=0)
    frame = encode_frame(**cols, t_s=0, last_plot_s=0, sequence=0)
    with pytest.raises(ValueError, match="expected 133 bytes"):
        decode_frame(frame[:-1])
    with pytest.raises(ValueError, match="magic at byte 0"):
        decode_frame(b"XXXX" + frame[4:])


def test_stamp_sent_time_changes_only_the_stamp():
    frame = encode_frame(**_columns(4), t_s=5.0, last_plot_s=4.0, sequence=9, sent_unix_s=1.0)
    stamped = stamp_sent_time(frame, 123.5)
    assert decode_frame(stamped)["sent_unix_s"] == 123.5
    assert stamped[:32] == frame[:32] and stamped[40:] == frame[40:]


def test_hello_and_labels_messages():
    sensors = SensorSet(Origin(46.0, 7.0, 400.0), [
        Sensor("r1", "radar-2d", lat=46.1, lon=7.2, max_range_m=150e3),
        Sensor("r2", "radar-3d", x=10_000.0, y=0.0, max_range_m=90e3),
        Sensor("ads", "adsb"),
    ], epoch_utc="2026-11-25T00:00:00Z")
    hello = json.loads(hello_message(sensors, trail_s=60))
    assert hello["type"] == "hello" and hello["epoch_utc"] == "2026-11-25T00:00:00Z" and hello["trail_s"] == 60
    assert hello["origin"] == {"lat": 46.0, "lon": 7.0, "alt_m": 400.0}
    r1, r2, ads = hello["sensors"]
    assert r1 == {"name": "r1", "type": "radar-2d", "lat": 46.1, "lon": 7.2, "max_range_m": 150e3}
    # 10 km east of the origin at 46 deg N: 10 km over the WGS84 parallel radius N cos(lat) = 4438.5 km
    assert r2["lat"] == pytest.approx(46.0, abs=1e-3) and r2["lon"] == pytest.approx(7.0 + 0.129088, abs=1e-5)
    assert ads["lat"] is None and ads["type"] == "adsb"
    labels = json.loads(labels_message({12: {"callsign": "SWR123", "icao24": "4b1234"}, 5: {"icao24": "abcdef"}}))
    assert labels == {"type": "labels", "labels": {"12": {"callsign": "SWR123", "icao24": "4b1234"},
                                                   "5": {"callsign": None, "icao24": "abcdef"}}}

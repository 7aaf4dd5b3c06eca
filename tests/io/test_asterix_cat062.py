"""CAT062 system tracks (issue 11 item 2): the vectorised encoder against libasterix byte for byte,
libasterix's decoding of the file within the items' resolutions, errors naming row and column,
the chunked writer, and ``skytrack track ... -o tracks.ast`` against the Parquet tracks."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from skytrack.io.asterix.cat062 import (
    DEFAULT_SYSTEM_SAC_SIC,
    Cat062Writer,
    encode_cat062,
    quantise_tracks,
    reference_records,
    system_sac_sic,
    time_of_day_at_epoch,
)
from skytrack.io.asterix.cat062_read import decode_cat062, decode_cat062_libasterix

FT = 0.3048
#: half an LSB of every item (rounding to the nearest LSB), plus float slack
HALF = {"x": 0.25, "y": 0.25, "vx": 0.125, "vy": 0.125, "lat": 90.0 / 2**25, "lon": 90.0 / 2**25,
        "time": 1.0 / 256, "alt_geometric": 3.125 * FT, "alt_flight_level": 12.5 * FT, "vz": 3.125 * FT / 60.0}
SLACK = 1e-9


def random_tracks(n: int, seed: int) -> pd.DataFrame:
    """Tracks rows with every optional field present on some rows and absent on others, 2-D and 3-D."""
    rng = np.random.default_rng(seed)
    three_d = rng.random(n) < 0.5

    def maybe(p, values):
        return np.where(rng.random(n) < p, values, np.nan)

    codes = np.array(["7000", "0123", "7777", "0000", None], dtype=object)
    addresses = np.array(["abc123", "00ff01", "ffffff", None], dtype=object)
    callsigns = np.array(["AFR1234", "EZY9 ", "BAW12345", "A", None], dtype=object)
    statuses = np.array(["confirmed", "coasting", None], dtype=object)
    frame = pd.DataFrame({
        "time": np.sort(rng.uniform(0, 900, n)),
        "track_id": rng.integers(0, 200_000, n),
        "x": rng.uniform(-4.0e6, 4.0e6, n), "y": rng.uniform(-4.0e6, 4.0e6, n),
        "z": np.where(three_d, rng.uniform(-500, 12_000, n), np.nan),
        "vx": maybe(0.9, rng.uniform(-800, 800, n)), "vy": rng.uniform(-800, 800, n),
        "vz": maybe(0.5, rng.uniform(-100, 100, n)),
        "var_x": maybe(0.8, rng.uniform(0, 3e3, n) ** 2), "var_y": rng.uniform(0, 3e3, n) ** 2,
        "var_z": maybe(0.7, rng.uniform(0, 600, n) ** 2),
        "var_vx": maybe(0.8, rng.uniform(0, 80, n) ** 2), "var_vy": rng.uniform(0, 80, n) ** 2,
        "lat": maybe(0.9, rng.uniform(-90, 90, n)), "lon": rng.uniform(-180, 180, n),
        "alt_m": maybe(0.8, rng.uniform(-400, 15_000, n)),
        "status": statuses[rng.integers(0, 3, n)],
        "mode3a": codes[rng.integers(0, 5, n)], "icao24": addresses[rng.integers(0, 4, n)],
        "callsign": callsigns[rng.integers(0, 5, n)],
    })
    frame.loc[0, "track_id"] = 65_535
    frame.loc[1, "track_id"] = 65_536 + 17
    return frame


def texts(column) -> list:
    return [None if pd.isna(v) else v for v in column]


def libasterix_bytes(raw: dict, records_per_block: int) -> bytes:
    import asterix.generated as gen

    records = reference_records(raw)
    return b"".join(gen.Cat_062_1_21.create(records[k:k + records_per_block]).unparse().to_bytes()
                    for k in range(0, len(records), records_per_block))


@pytest.mark.parametrize("records_per_block", [128, 7, 1])
def test_vectorised_encoder_writes_libasterix_bytes(records_per_block):
    tracks = random_tracks(400, seed=records_per_block)
    settings = {"sac_sic": (12, 34), "service_id": 9, "time_of_day_at_epoch_s": 86_000.0, "monosensor": True}
    ours = encode_cat062(tracks, max_records_per_block=records_per_block, **settings)
    assert ours == libasterix_bytes(quantise_tracks(tracks, **settings), records_per_block)
    assert ours[0] == 62


def _close(got, want, tolerance, name):
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert np.array_equal(np.isnan(got), np.isnan(want)), name
    known = ~np.isnan(want)
    assert np.abs(got[known] - want[known]).max(initial=0.0) <= tolerance + SLACK, name


def test_libasterix_decodes_the_tracks_within_the_resolutions():
    tracks = random_tracks(300, seed=3)
    epoch_time_of_day = 86_000.0  # the tracks cross midnight 400 s after the epoch
    decoded = decode_cat062(encode_cat062(tracks, time_of_day_at_epoch_s=epoch_time_of_day, sac_sic=(5, 6)),
                            time_of_day_at_epoch_s=epoch_time_of_day)
    assert len(decoded) == len(tracks)
    for name in ("time", "x", "y", "vz"):
        _close(decoded[name], tracks[name], HALF[name], name)
    has_velocity = tracks["vx"].notna().to_numpy()
    _close(decoded["vx"], tracks["vx"], HALF["vx"], "vx")
    _close(decoded["vy"], np.where(has_velocity, tracks["vy"], np.nan), HALF["vy"], "vy")
    has_position = tracks["lat"].notna().to_numpy()
    _close(decoded["lat"], tracks["lat"], HALF["lat"], "lat")
    _close(decoded["lon"], np.where(has_position, tracks["lon"], np.nan), HALF["lon"], "lon")
    geometric = (tracks["z"].notna() & tracks["alt_m"].notna()).to_numpy()  # I062/130 (3-D), else I062/136
    alt = tracks["alt_m"].to_numpy()
    _close(decoded["alt_m"].to_numpy()[geometric], alt[geometric], HALF["alt_geometric"], "alt_m (I062/130)")
    _close(decoded["alt_m"].to_numpy()[~geometric], alt[~geometric], HALF["alt_flight_level"], "alt_m (I062/136)")
    assert (decoded["track_id"].to_numpy() == tracks["track_id"].to_numpy() % 65536).all()
    assert decoded["track_id"].iloc[:2].tolist() == [65_535, 17]
    for name in ("status", "mode3a", "icao24"):
        assert texts(decoded[name]) == texts(tracks[name]), name
    assert texts(decoded["callsign"]) == [None if c is None else c.strip() for c in texts(tracks["callsign"])]
    assert set(decoded["sac"]) == {5} and set(decoded["sic"]) == {6} and set(decoded["service_id"]) == {1}
    first_rows = np.zeros(len(tracks), bool)
    first_rows[np.unique(tracks["track_id"], return_index=True)[1]] = True
    assert (decoded["track_begin"].to_numpy() == first_rows).all()
    # accuracies: standard deviations to half an LSB, or the subfield's maximum when larger
    for name, lsb, top in (("var_x", 0.5, 65535 * 0.5), ("var_y", 0.5, 65535 * 0.5),
                           ("var_vx", 0.25, 255 * 0.25), ("var_vy", 0.25, 255 * 0.25)):
        want = np.minimum(np.sqrt(tracks[name].to_numpy()), top)
        if name == "var_vy":
            want = np.where(tracks["var_vx"].notna(), want, np.nan)  # ATV carries both or none
        if name == "var_y":
            want = np.where(tracks["var_x"].notna(), want, np.nan)
        _close(np.sqrt(decoded[name]), want, lsb / 2, name)
    want_z = np.where(geometric, np.minimum(np.sqrt(tracks["var_z"].to_numpy()), 255 * 6.25 * FT), np.nan)
    _close(np.sqrt(decoded["var_z"]), want_z, 6.25 * FT / 2, "var_z")


@pytest.mark.parametrize(("column", "value", "message"), [
    ("x", 4.2e6, "row 3, column x"), ("vy", 9000.0, "row 3, column vy"), ("callsign", "TOO LONG1", "row 3, column callsign"),
    ("callsign", "ab-1", "row 3, column callsign"), ("mode3a", "7080", "row 3, column mode3a"),
    ("icao24", "12345", "row 3, column icao24"), ("time", np.nan, "row 3, column time"),
])
def test_a_value_the_item_cannot_hold_names_row_and_column(column, value, message):
    tracks = random_tracks(6, seed=1)
    tracks[column] = tracks[column].astype(object)
    tracks.loc[3, column] = value
    with pytest.raises(ValueError, match=message):
        encode_cat062(tracks)


def test_the_writer_marks_a_track_begin_once_over_the_chunks(tmp_path):
    tracks = random_tracks(200, seed=8)
    tracks["track_id"] = np.arange(200) % 13
    with_epoch = type("Sensors", (), {"sensors": [], "extra": {"system": {"sac": 7, "sic": 8}},
                                      "epoch_utc": "2024-01-10T23:59:00Z"})()
    writer = Cat062Writer(tmp_path / "t.ast", with_epoch)
    for start in range(0, 200, 37):
        writer.write(tracks.iloc[start:start + 37])
    writer.close()
    decoded = decode_cat062((tmp_path / "t.ast").read_bytes(), time_of_day_at_epoch_s=86_340.0)
    assert writer.rows == len(decoded) == 200
    assert decoded["track_begin"].to_numpy().nonzero()[0].tolist() == list(range(13))
    assert (decoded["sac"] == 7).all() and (decoded["sic"] == 8).all()
    _close(decoded["time"], tracks["time"], HALF["time"], "time")


def test_system_sac_sic_and_epoch_time_of_day():
    assert system_sac_sic({"system": {"sac": 1, "sic": 2}}) == (1, 2)
    assert system_sac_sic({}) == system_sac_sic(None) == DEFAULT_SYSTEM_SAC_SIC
    with pytest.raises(ValueError, match="system SAC/SIC must be in"):
        system_sac_sic({"system": {"sac": 256, "sic": 2}})
    with pytest.raises(ValueError, match='"system" must be'):
        system_sac_sic({"system": {"sac": 1}})
    assert time_of_day_at_epoch("2024-01-10T08:00:30.5Z") == 8 * 3600 + 30.5
    assert time_of_day_at_epoch(None) == 0.0


def test_decoding_names_a_bad_block_and_counts_other_categories():
    good = encode_cat062(random_tracks(3, seed=2))
    other = bytes([48, 0, 3])
    decoded = decode_cat062(other + good)
    assert len(decoded) == 3 and decoded.attrs["skipped_blocks"] == [(0, 48)]
    with pytest.raises(ValueError, match=f"byte offset {len(good)} \\(block 1\\): bad block length"):
        decode_cat062(good + bytes([62, 0, 200, 1]))


def assert_same_frames(got: pd.DataFrame, want: pd.DataFrame) -> None:
    assert list(got.columns) == list(want.columns) and len(got) == len(want)
    for name in want.columns:
        a, b = got[name].to_numpy(), want[name].to_numpy()
        if b.dtype.kind == "f":
            assert np.array_equal(a.astype(float), b, equal_nan=True), name
        else:
            assert texts(a) == texts(b), name


def test_the_numpy_engine_reads_what_libasterix_reads():
    data = encode_cat062(random_tracks(300, seed=11), time_of_day_at_epoch_s=86_000.0)
    settings = {"time_of_day_at_epoch_s": 86_000.0}
    fast, reference = decode_cat062(data, engine="numpy", **settings), decode_cat062(data, engine="libasterix", **settings)
    assert len(fast) == len(reference) == 300
    assert_same_frames(fast, reference)


#: items skytrack does not write, as another system may send them (the numpy engine steps over them)
FOREIGN_ITEMS = {
    "210": 0x1234, "245": 0x41C3, "290": {"TRK": 5, "ADS": 300, "MLT": 7}, "295": {"MFL": 1, "MD2": 2, "MB": 9},
    "390": {"TAG": 0x0102, "TOD": [0x01020304, 0x05060708], "PEC": 5}, "270": ((16, None), (32, None)),
    "340": {"SID": 0x0203, "POS": 0x01020304, "TYP": 0x20}, "135": 0x0100, "200": 0x10, "120": 5, "300": 3,
    "500": {"APC": 0x00100020, "COV": 7, "APW": 5, "AGA": 3, "ATV": 0x0102, "AA": 9, "ARC": 4},
    "380": {"ADR": 0xABC123, "MHG": 0x100, "TIS": ((1, 0, 0, None),), "TID": [0, 0],
            "BDSDATA": [0x1122334455667788], "BPS": 3},
}


def _foreign_data(with_510: bool) -> bytes:
    import asterix.generated as gen

    spec = gen.Cat_062_1_21
    raw = quantise_tracks(random_tracks(14, seed=4))
    records = reference_records(raw)
    for k, (item, value) in enumerate(FOREIGN_ITEMS.items()):
        records[k] = records[k].set_item(item, value)
    if with_510:
        records[-1] = records[-1].set_item("510", [(1, 2)])
    return spec.create(records).unparse().to_bytes()


def test_the_numpy_engine_steps_over_items_it_does_not_read():
    data = _foreign_data(with_510=False)
    frame = decode_cat062(data, engine="numpy")
    assert_same_frames(frame, decode_cat062(data, engine="libasterix"))
    assert list(FOREIGN_ITEMS)[11:] == ["500", "380"]
    assert frame["icao24"].iloc[12] == "abc123"
    assert frame["var_vx"].iloc[11] == (1 * 0.25) ** 2 and frame["var_vy"].iloc[11] == (2 * 0.25) ** 2


def test_input_the_scan_cannot_walk_goes_to_libasterix():
    data = _foreign_data(with_510=True)  # I062/510: elements that end in FX
    with pytest.raises(ValueError, match="numpy engine cannot walk"):
        decode_cat062(data, engine="numpy")
    frame = decode_cat062(data)
    assert_same_frames(frame, decode_cat062(data, engine="libasterix"))
    assert len(frame) == len(decode_cat062_libasterix(data)[0]) == 14

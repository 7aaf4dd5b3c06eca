"""The numpy CAT021 encoder (``cat021.cat021_record_bytes``, ``encode_cat021_blocks``) against libasterix
(``encode_cat021`` + ``cat021_blocks``), byte for byte (issue 11 item 2: I021/010, 040, 071, 131, 080,
140, 090, 157, 160, 170).

Random ADS-B tables where every optional item (090 NACp from ``nacp`` or ``sigma_m``, 170 callsign,
160 ground vector with and without 157 vertical rate, RE set on speeds and rates beyond the fields)
is present on some rows and absent on others, plus the extremes of every field; values an item
cannot hold are errors naming the row and the column; the simulated recording writes these bytes.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from skytrack.geo.sensors import Origin
from skytrack.io.asterix.bytes_assembly import blocks_from_records
from skytrack.io.asterix.cat021 import (
    FEET_M,
    HEIGHT_LSB_FT,
    cat021_blocks,
    cat021_record_bytes,
    encode_cat021,
    encode_cat021_blocks,
    quantise_adsb,
)
from skytrack.io.asterix.recording import encode_recording

ORIGIN = Origin(47.0, 8.0, 400.0)


def random_adsb(n: int, seed: int) -> pd.DataFrame:
    """Every combination of 090 (from nacp / from sigma_m / none), 170, 160, 157 over the rows, plus extremes."""
    rng = np.random.default_rng(seed)
    combos = np.array(list(itertools.product([0, 1, 2], [False, True], [False, True], [False, True])))
    flags = combos[np.arange(n) % len(combos)]
    letters = np.array(list("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 "))
    callsigns = ["".join(rng.choice(letters, rng.integers(1, 9))) for _ in range(n)]
    speed = rng.uniform(-300, 300, (n, 2))
    speed[::7] *= 20  # some ground speeds beyond 2^15 - 1 LSB (about 3 400 m/s): written with RE
    climb = rng.uniform(-50, 50, n)
    climb[::5] *= 30  # some rates beyond 2^14 - 1 LSB (about 520 m/s): written with RE
    adsb = pd.DataFrame({
        "time": rng.uniform(-200, 90_000, n),
        "icao24": [f"{a:06x}" for a in rng.integers(0, 1 << 24, n)],
        "lat": np.where(flags[:, 2], ORIGIN.lat + rng.uniform(-3, 3, n), rng.uniform(-90, 90, n)),
        "lon": np.where(flags[:, 2], ORIGIN.lon + rng.uniform(-3, 3, n), rng.uniform(-180, 180, n)),
        "alt_m": rng.uniform(-1000, 20_000, n),
        "nacp": np.where(flags[:, 0] == 1, rng.integers(0, 16, n), np.nan),
        "sigma_m": np.where(flags[:, 0] == 2, rng.lognormal(2, 3, n), np.nan),
        "callsign": pd.Series([c if f else None for c, f in zip(callsigns, flags[:, 1])], dtype=object),
        "vx": np.where(flags[:, 2], speed[:, 0], np.nan),
        "vy": np.where(flags[:, 2], speed[:, 1], np.nan),
        "vz": np.where(flags[:, 2] & flags[:, 3], climb, np.nan),
    })
    top_height = (2**15 - 1) * HEIGHT_LSB_FT * FEET_M
    extremes = {"lat": [-90.0, 90.0, 0.0], "lon": [-180.0, 180.0, 179.9999999], "alt_m": [-(2**15) * HEIGHT_LSB_FT
                * FEET_M, top_height, 0.0], "icao24": ["000000", "ffffff", "ABCDEF"],
                "callsign": ["ZZZZZZZZ", " 0 ", "   "], "nacp": [0.0, 15.0, np.nan], "time": [0.0, 86_399.999, -0.001]}
    for column, values in extremes.items():
        adsb.loc[[0, 1, 2], column] = values
    return adsb


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_numpy_records_are_libasterix_bytes(seed):
    adsb = random_adsb(600, seed)
    settings = {"time_of_day_at_epoch_s": 86_000.0 if seed == 2 else 3_600.0, "origin": ORIGIN}
    raw = quantise_adsb(adsb, (7, 201), **settings)
    for flag in ("has_090", "has_170", "has_160", "has_157", "speed_exceeded", "rate_exceeded"):
        assert 0 < raw[flag].sum() < len(adsb), flag  # present on some rows, absent on others
    assert not raw["has_170"][2] and raw["has_170"][1]  # a blank callsign writes no I021/170
    records, starts = cat021_record_bytes(adsb, (7, 201), **settings)
    reference = [record.unparse().to_bytes() for record in encode_cat021(adsb, (7, 201), **settings)]
    assert starts.size == len(adsb) + 1
    for i, expected in enumerate(reference):
        assert records[starts[i]:starts[i + 1]].tobytes() == expected, f"row {i}"
    ours = encode_cat021_blocks(adsb, (7, 201), max_records_per_block=50, **settings)
    assert ours == cat021_blocks(encode_cat021(adsb, (7, 201), **settings), max_records_per_block=50)


def test_tables_without_optional_columns_and_empty_tables():
    adsb = random_adsb(40, 4)[["time", "icao24", "lat", "lon", "alt_m"]]
    assert encode_cat021_blocks(adsb, (0, 101)) == cat021_blocks(encode_cat021(adsb, (0, 101)))
    records, starts = cat021_record_bytes(adsb.iloc[:0], (0, 101))
    assert records.size == 0 and starts.tolist() == [0]
    assert encode_cat021_blocks(adsb.iloc[:0], (0, 101)) == b""


@pytest.mark.parametrize(("column", "value", "row"), [
    ("lat", 90.0 + 1e-6, 3), ("alt_m", 2**15 * HEIGHT_LSB_FT * FEET_M, 5), ("alt_m", np.nan, 6), ("lon", 181.0, 2),
    ("nacp", 16.0, 4), ("nacp", -1.0, 1), ("icao24", "1000000", 7), ("icao24", "xyz", 3), ("icao24", None, 8),
    ("callsign", "TOOLONG99", 9), ("callsign", "KLM-12", 0), ("time", np.inf, 5),
])
def test_values_an_item_cannot_hold_name_row_and_column(column, value, row):
    adsb = random_adsb(12, 5)
    adsb[column] = adsb[column].astype(object) if isinstance(value, str) or value is None else adsb[column]
    adsb.loc[row, column] = value
    with pytest.raises(ValueError, match=f"^adsb: row {row}, column {column}:"):
        cat021_record_bytes(adsb, (1, 2), origin=ORIGIN)
    with pytest.raises(ValueError, match=f"^adsb: row {row}, column {column}:"):
        encode_cat021(adsb, (1, 2), origin=ORIGIN)


def test_velocities_need_an_origin_and_sac_sic_must_fit():
    adsb = random_adsb(20, 6)
    with pytest.raises(ValueError, match="origin"):
        cat021_record_bytes(adsb, (1, 2))
    with pytest.raises(ValueError, match="SAC/SIC"):
        cat021_record_bytes(adsb, (1, 256), origin=ORIGIN)


def test_the_simulated_recording_writes_the_libasterix_records():
    adsb = random_adsb(300, 7).sort_values("time", kind="stable").reset_index(drop=True)
    empty_plots = pd.DataFrame({"time": np.empty(0), "sensor": np.empty(0, object), "range_m": np.empty(0),
                                "azimuth_deg": np.empty(0)})
    data = encode_recording(empty_plots, {}, adsb=adsb, adsb_sac_sic=(0, 101), origin=ORIGIN,
                            time_of_day_at_epoch_s=100.0)
    chunks = [r.unparse().to_bytes() for r in encode_cat021(adsb, (0, 101), origin=ORIGIN,
                                                             time_of_day_at_epoch_s=100.0)]
    starts = np.concatenate([[0], np.cumsum([len(c) for c in chunks])]).astype(np.int64)
    assert data == blocks_from_records(np.frombuffer(b"".join(chunks), np.uint8), starts, 128, 21)

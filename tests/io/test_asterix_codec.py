"""ASTERIX CAT048 / CAT034 (skytrack.io.asterix): the numpy decoder against libasterix, record for record.

Random plots with every combination of the optional items (I048/070, 090, 220) and both
kinds of sensor (PSR + SSR, SSR only) are encoded with libasterix; the vectorised decoder
must give, record for record, the raw values libasterix's own decoder gives (0 LSB apart)
and the plots' values within half an LSB.  Also: service messages, the time-of-day
unwrap over midnight, block splitting, and items skipped by structure (I048/130, 161,
170, 250, SP, ...).
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from asterix.base import Bits, RawDatablock
import asterix.generated as gen

from skytrack.io.asterix import decode_asterix, encode_asterix
from skytrack.io.asterix import units as u

CAT048, CAT034 = gen.Cat_048_1_32, gen.Cat_034_1_29
SAC_SIC = {"north": (12, 34), "south": (200, 7), "ssr": (0, 255)}


def random_plots(n: int, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    combos = np.array(list(itertools.product([False, True], repeat=3)))
    flags = combos[np.arange(n) % len(combos)]  # every combination of 070 / 090 / 220, many times
    plots = pd.DataFrame({
        "time": np.sort(rng.uniform(0, 600, n)),
        "sensor": rng.choice(list(SAC_SIC), n),
        "range_m": rng.uniform(0, 255.9 * u.NAUTICAL_MILE_M, n),
        "azimuth_deg": rng.uniform(0, 360, n),
        "mode3a": [f"{c:04o}" if f else None for c, f in zip(rng.integers(0, 0o10000, n), flags[:, 0])],
        "mode_c_ft": np.where(flags[:, 1], rng.uniform(-1500, 130000, n), np.nan),
        "mode_s": [f"{a:06x}" if f else None for a, f in zip(rng.integers(0, 1 << 24, n), flags[:, 2])],
    })
    plots.loc[0, ["range_m", "azimuth_deg", "mode3a", "mode_c_ft", "mode_s"]] = [0.0, 0.0, "0000", -1500.0, "000000"]
    plots.loc[1, ["range_m", "azimuth_deg", "mode3a", "mode_c_ft", "mode_s"]] = [
        65535 * u.RHO_LSB_M, 359.999, "7777", 130000.0, "ffffff"]
    return plots


def reference_records(data: bytes) -> list[tuple[int, object]]:
    """(category, libasterix record) for every record, in input order."""
    blocks = RawDatablock.parse(Bits.from_bytes(data))
    assert not isinstance(blocks, ValueError)
    out = []
    for block in blocks:
        spec = {48: CAT048, 34: CAT034}[block.get_category()]
        records = spec.cv_uap.parse(block.get_raw_records())
        assert not isinstance(records, ValueError)
        out.extend((block.get_category(), r) for r in records)
    return out


def _sub(record, item: str, sub: str):
    found = record.get_item(item)
    return None if found is None else found.variation.get_item(sub).variation.content


@pytest.fixture(scope="module")
def encoded():
    plots = random_plots(400, seed=11)
    data = encode_asterix(plots, SAC_SIC, ssr_only_sensors=["ssr"], time_of_day_at_epoch_s=3600.0,
                          max_records_per_block=37)
    return plots, data, decode_asterix(data, strict=True)


def test_every_cat048_record_equals_libasterix(encoded):
    plots, data, decoded = encoded
    reference = [r for cat, r in reference_records(data) if cat == 48]
    p = decoded.plots
    assert len(reference) == len(plots) == p["range_m"].size
    for i, rec in enumerate(reference):
        assert (p["sac"][i], p["sic"][i]) == (_sub(rec, "010", "SAC").as_uint(), _sub(rec, "010", "SIC").as_uint())
        assert p["time_of_day_s"][i] == rec.get_item("140").variation.content.as_uint() * u.TIME_LSB_S
        assert p["time_of_day_s"][i] == pytest.approx(rec.get_item("140").variation.content.as_quantity("s"), abs=1e-12)
        assert p["detection_type"][i] == _sub(rec, "020", "TYP").as_uint()
        assert p["range_m"][i] == _sub(rec, "040", "RHO").as_uint() * u.RHO_LSB_M
        assert p["range_m"][i] == pytest.approx(_sub(rec, "040", "RHO").as_quantity("NM") * 1852.0, rel=1e-15, abs=1e-12)
        assert p["azimuth_deg"][i] == _sub(rec, "040", "THETA").as_uint() * u.THETA_LSB_DEG
        assert p["azimuth_deg"][i] == pytest.approx(_sub(rec, "040", "THETA").as_quantity("°"), abs=1e-12)
        mode3a = _sub(rec, "070", "MODE3A")
        assert p["mode3a"][i] == (None if mode3a is None else mode3a.as_string())
        assert p["mode3a_code"][i] == (-1 if mode3a is None else mode3a.as_uint())
        level = _sub(rec, "090", "FL")
        if level is None:
            assert np.isnan(p["mode_c_ft"][i])
        else:
            assert p["mode_c_ft"][i] == pytest.approx(level.as_quantity("FL") * 100.0, abs=1e-9)
        address = rec.get_item("220")
        assert p["mode_s"][i] == (None if address is None else f"{address.variation.content.as_uint():06x}")
        assert p["mode_s_address"][i] == (-1 if address is None else address.variation.content.as_uint())


def test_decoded_plots_equal_the_encoded_plots_within_half_an_lsb(encoded):
    plots, _, decoded = encoded
    p = decoded.plots
    order = np.argsort(plots["time"].to_numpy(), kind="stable")  # encoder writes in time order
    plots = plots.iloc[order].reset_index(drop=True)
    assert np.all(np.abs(p["range_m"] - plots["range_m"]) <= u.RHO_LSB_M / 2 + 1e-9)
    wrapped = np.abs((p["azimuth_deg"] - plots["azimuth_deg"] + 180.0) % 360.0 - 180.0)
    assert np.all(wrapped <= u.THETA_LSB_DEG / 2 + 1e-9)
    assert np.all(np.abs(p["time"] - (plots["time"] + 3600.0)) <= u.TIME_LSB_S / 2 + 1e-9)
    level = plots["mode_c_ft"].to_numpy()
    assert np.array_equal(np.isnan(p["mode_c_ft"]), np.isnan(level))
    assert np.nanmax(np.abs(p["mode_c_ft"] - level)) <= u.FLIGHT_LEVEL_LSB_FT / 2 + 1e-9
    assert list(p["mode3a"]) == [None if pd.isna(v) else v for v in plots["mode3a"]]
    assert list(p["mode_s"]) == [None if pd.isna(v) else v for v in plots["mode_s"]]
    assert list(p["sensor"]) == [f"{SAC_SIC[s][0]}/{SAC_SIC[s][1]}" for s in plots["sensor"]]
    # TYP from what the plot has: Mode S 5 / 7, SSR 2 / 3, PSR 1, nothing on an SSR-only sensor 0
    has_s, has_ssr = plots["mode_s"].notna(), plots[["mode3a", "mode_c_ft", "mode_s"]].notna().any(axis=1)
    primary = plots["sensor"] != "ssr"
    expected = np.select([has_s & primary, has_s, has_ssr & primary, has_ssr, primary], [7, 5, 3, 2, 1], 0)
    assert np.array_equal(p["detection_type"], expected)


def test_sensor_names_come_from_sac_sic_when_given(encoded):
    plots, data, _ = encoded
    names = {ids: name for name, ids in SAC_SIC.items() if name != "ssr"}
    decoded = decode_asterix(data, sensor_names=names)
    expected = plots["sensor"].iloc[np.argsort(plots["time"].to_numpy(), kind="stable")].replace({"ssr": "0/255"})
    assert list(decoded.plots["sensor"]) == list(expected)


def test_blocks_are_category_runs_of_at_most_the_given_records(encoded):
    _, data, decoded = encoded
    assert decoded.problems.blocks == -(-400 // 37)
    assert decoded.problems.records == 400 and decoded.problems.count == 0
    assert data[0] == 48 and int.from_bytes(data[1:3], "big") < len(data)


def test_service_messages_and_north_marker_times_equal_libasterix():
    service = pd.DataFrame({"time": [0.0, 1.0, 2.0, 4.0, 4.0, 5.5],
                            "sensor": ["north", "north", "south", "north", "south", "north"],
                            "message": ["north_marker", "sector_crossing", "north_marker", "north_marker",
                                        "sector_crossing", "sector_crossing"],
                            "azimuth_deg": [np.nan, 45.0, np.nan, np.nan, 359.0, 180.7]})
    plots = random_plots(8, seed=3).assign(time=[0.5, 0.5, 1.5, 3.0, 4.0, 4.5, 5.0, 6.0], sensor="north")
    data = encode_asterix(plots, SAC_SIC, service=service, time_of_day_at_epoch_s=100.0)
    decoded = decode_asterix(data, strict=True)
    reference = reference_records(data)
    assert [c for c, _ in reference] == [34, 48, 48, 34, 48, 34, 48, 34, 34, 48, 48, 48, 34, 48]
    assert decoded.problems.blocks == 10
    s = decoded.service
    ref = [r for c, r in reference if c == 34]
    assert list(s["message_type"]) == [r.get_item("000").variation.content.as_uint() for r in ref] == [1, 2, 1, 1, 2, 2]
    assert list(s["time_of_day_s"]) == [r.get_item("030").variation.content.as_uint() / 128 for r in ref]
    assert list(s["time"]) == [100.0, 101.0, 102.0, 104.0, 104.0, 105.5]
    sector = [r.get_item("020") for r in ref]
    assert [None if a is None else a.variation.content.as_uint() * u.SECTOR_LSB_DEG for a in sector] == \
        [None if np.isnan(a) else a for a in s["azimuth_deg"]]
    assert s["azimuth_deg"][1] == 45.0 and s["azimuth_deg"][4] == 255 * u.SECTOR_LSB_DEG and s["azimuth_deg"][5] == 180.0
    markers = decoded.north_marker_times()
    assert set(markers) == {(12, 34), (200, 7)}
    assert list(markers[(12, 34)]) == [100.0, 104.0] and list(markers[(200, 7)]) == [102.0]


def test_time_of_day_unwraps_over_midnight_per_sensor():
    plots = random_plots(6, seed=5).assign(time=[0.0, 0.5, 1.0, 1.5, 2.0, 2.5],
                                           sensor=["north", "south", "north", "north", "south", "north"])
    decoded = decode_asterix(encode_asterix(plots, SAC_SIC, time_of_day_at_epoch_s=86399.0))
    assert list(decoded.plots["time_of_day_s"]) == [86399.0, 86399.5, 0.0, 0.5, 1.0, 1.5]
    assert list(decoded.plots["time"]) == [86399.0, 86399.5, 86400.0, 86400.5, 86401.0, 86401.5]


def test_items_not_read_are_skipped_by_their_structure():
    base = {"010": (("SAC", 1), ("SIC", 2)), "140": 640, "040": (("RHO", 512), ("THETA", 16384))}
    extras = [{"161": 7}, {"170": (0, 0)}, {"130": {"SRL": 3, "PAM": 4}}, {"250": [1, 2]}, {"SP": b"abc"},
              {"120": {"CAL": 5}}, {"230": 0, "030": (0,), "240": 0, "042": 0, "200": 0, "210": 0, "080": 0,
                                    "100": 0, "110": 0, "260": 0, "055": 0, "050": 0, "065": 0, "060": 0}]
    records = [CAT048.cv_record.create({**base, **extra, "140": 640 + i}) for i, extra in enumerate(extras)]
    service = [CAT034.cv_record.create({"000": 1, "010": (("SAC", 1), ("SIC", 2)), "030": 100,
                                        "050": {"COM": 1, "MDS": 3}, "060": {"PSR": 2}, "070": [1, 2, 3], "041": 1,
                                        "100": 0, "110": 0, "120": 0, "090": 0})]
    data = CAT048.create(records).unparse().to_bytes() + CAT034.create(service).unparse().to_bytes()
    decoded = decode_asterix(data, strict=True)
    assert list(decoded.plots["time_of_day_s"]) == [5.0 + i / 128 for i in range(len(extras))]
    assert np.all(decoded.plots["range_m"] == 2 * u.NAUTICAL_MILE_M)
    assert np.all(decoded.plots["azimuth_deg"] == 90.0)
    assert list(decoded.service["time_of_day_s"]) == [100 / 128]


def test_encoder_names_the_row_of_a_value_the_items_cannot_hold():
    plots = random_plots(4, seed=1)
    plots.loc[2, "range_m"] = 257 * u.NAUTICAL_MILE_M
    with pytest.raises(ValueError, match="row 2, column range_m"):
        encode_asterix(plots, SAC_SIC)
    plots = random_plots(4, seed=1)
    plots.loc[3, "time"] = np.nan
    with pytest.raises(ValueError, match="row 3, column time: a finite number"):
        encode_asterix(plots, SAC_SIC)
    with pytest.raises(ValueError, match="no SAC/SIC for sensor"):
        encode_asterix(random_plots(4, seed=1), {"north": (1, 1)})


def test_empty_input_and_array_input():
    empty = decode_asterix(b"", strict=True)
    assert empty.plots["range_m"].size == 0 and empty.service["time"].size == 0
    assert (empty.problems.blocks, empty.problems.records, empty.problems.count) == (0, 0, 0)
    data = encode_asterix(random_plots(8, seed=4), SAC_SIC)
    from_array = decode_asterix(np.frombuffer(data, np.uint8))
    assert list(from_array.plots["range_m"]) == list(decode_asterix(data).plots["range_m"])
    assert from_array.plots["range_m"].size == 8

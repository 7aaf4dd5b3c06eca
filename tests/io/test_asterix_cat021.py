"""ASTERIX CAT021 ADS-B reports (skytrack.io.asterix.cat021): the numpy decoder against libasterix.

Random reports with every combination of the optional items (I021/090 NACp, 170 callsign,
160 ground vector, 157 vertical rate) and extreme values are encoded with
``encode_cat021``; the decoder must give, record for record, the raw values libasterix's own
decoder gives (0 LSB apart) and the reports' values within half an LSB.  Records written
directly with libasterix exercise the alternative items (I021/073, 130, 145, 155) and the
items skipped by structure (161, 015, 072, 210, 220, 110, 295, 250, ...).  The framing's
CAT021 UAP table is checked against libasterix's specification item by item.
"""

from __future__ import annotations

import itertools

import asterix.generated as gen
import numpy as np
import pandas as pd
import pytest
from asterix.base import Bits, RawDatablock

from skytrack.geo.sensors import Origin
from skytrack.io.asterix import decode_asterix
from skytrack.io.asterix import cat021 as c21
from skytrack.io.asterix import framing
from skytrack.io.asterix import units as u
from skytrack.io.asterix.bytes_assembly import callsign_code
from skytrack.io.asterix.cat021 import cat021_blocks, decode_cat021, encode_cat021

CAT021 = gen.Cat_021_2_6
ORIGIN = Origin(47.0, 8.0, 400.0)


def random_reports(n: int, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    flags = np.array(list(itertools.product([False, True], repeat=4)))[np.arange(n) % 16]
    letters = np.array(list("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 "))
    reports = pd.DataFrame({
        "time": np.sort(rng.uniform(0, 900, n)),
        "icao24": [f"{a:06x}" for a in rng.integers(0, 1 << 24, n)],
        # moving reports near the origin (the ground vector is in the aircraft's own north-east frame)
        "lat": np.where(flags[:, 2], ORIGIN.lat + rng.uniform(-2, 2, n), rng.uniform(-90, 90, n)),
        "lon": np.where(flags[:, 2], ORIGIN.lon + rng.uniform(-2, 2, n), rng.uniform(-180, 180, n)),
        "alt_m": rng.uniform(-500, 15000, n),
        "nacp": np.where(flags[:, 0], rng.integers(0, 12, n), np.nan),
        "callsign": ["".join(rng.choice(letters, rng.integers(1, 9))).strip() or "A" if f else None
                     for f in flags[:, 1]],
        "vx": np.where(flags[:, 2], rng.uniform(-300, 300, n), np.nan),
        "vy": np.where(flags[:, 2], rng.uniform(-300, 300, n), np.nan),
        "vz": np.where(flags[:, 2] & flags[:, 3], rng.uniform(-50, 50, n), np.nan),
    })
    extremes = {"lat": [-90.0, 90.0], "lon": [-180.0, 179.9999999], "alt_m": [-2**15 * 6.25 * 0.3048,
                (2**15 - 1) * 6.25 * 0.3048], "icao24": ["000000", "ffffff"], "callsign": ["ZZZZZZZZ", "0"]}
    for column, values in extremes.items():
        reports.loc[[0, 1], column] = values
    return reports


def reference_records(data: bytes) -> list:
    blocks = RawDatablock.parse(Bits.from_bytes(data))
    assert not isinstance(blocks, ValueError)
    records = []
    for block in blocks:
        parsed = CAT021.cv_uap.parse(block.get_raw_records())
        assert not isinstance(parsed, ValueError)
        records.extend(parsed)
    return records


def _content(record, item: str, sub: str | None = None):
    found = record.get_item(item)
    if found is None:
        return None
    return found.variation.content if sub is None else found.variation.get_item(sub).variation.content


@pytest.fixture(scope="module")
def encoded():
    reports = random_reports(320, seed=21)
    data = cat021_blocks(encode_cat021(reports, (33, 44), time_of_day_at_epoch_s=86000.0, origin=ORIGIN),
                         max_records_per_block=50)
    decoded, problems = decode_cat021(data, strict=True, origin=ORIGIN)
    return reports, data, decoded


def test_every_record_equals_libasterix(encoded):
    reports, data, d = encoded
    reference = reference_records(data)
    assert len(reference) == len(reports) == len(d)
    for i, rec in enumerate(reference):
        assert (d["sac"][i], d["sic"][i]) == (_content(rec, "010", "SAC").as_uint(), _content(rec, "010", "SIC").as_uint())
        assert d["time_of_day_s"][i] == _content(rec, "071").as_uint() * u.TIME_LSB_S
        assert d["lat"][i] == _content(rec, "131", "LAT").as_quantity("°")
        assert d["lon"][i] == _content(rec, "131", "LON").as_quantity("°")
        assert d["alt_m"][i] == pytest.approx(_content(rec, "140").as_quantity("ft") * 0.3048, abs=1e-9)
        assert d["icao24_address"][i] == _content(rec, "080").as_uint()
        ident = _content(rec, "170")
        assert pd.isna(d["callsign"][i]) == (ident is None)
        if ident is not None:
            assert d["callsign"][i] == ident.as_string().rstrip()
        quality = rec.get_item("090")
        nacp = None if quality is None else quality.variation.get_item("NACP")
        assert np.isnan(d["nacp"][i]) == (nacp is None)
        if nacp is not None:
            assert d["nacp"][i] == nacp.variation.content.as_uint()
        ground = rec.get_item("160")
        assert np.isnan(d["ground_speed_mps"][i]) == (ground is None)
        if ground is not None:
            gs = ground.variation.get_item("GS").variation.content.as_quantity("NM/s")
            assert d["ground_speed_mps"][i] == pytest.approx(gs * u.NAUTICAL_MILE_M, abs=1e-9)
            assert d["track_deg"][i] == ground.variation.get_item("TA").variation.content.as_quantity("°")
        rate = _content(rec, "157", "GVR")
        assert np.isnan(d["vertical_rate_mps"][i]) == (rate is None)
        if rate is not None:
            assert d["vertical_rate_mps"][i] == pytest.approx(rate.as_quantity("ft/min") * 0.3048 / 60, abs=1e-9)


def test_reports_come_back_within_half_an_lsb(encoded):
    reports, _, d = encoded
    assert np.abs(d["lat"] - reports["lat"]).max() <= c21.LAT_LON_HIGH_LSB_DEG / 2 + 1e-12
    lon_error = np.mod(d["lon"] - reports["lon"] + 180, 360) - 180
    assert np.abs(lon_error).max() <= c21.LAT_LON_HIGH_LSB_DEG / 2 + 1e-9
    assert np.abs(d["alt_m"] - reports["alt_m"]).max() <= c21.HEIGHT_LSB_FT * c21.FEET_M / 2 + 1e-9
    assert np.abs(d["time"] - 86000.0 - reports["time"]).max() <= u.TIME_LSB_S / 2
    assert list(d["icao24"]) == list(reports["icao24"])
    given = reports["callsign"].to_numpy(object)
    assert [None if pd.isna(c) else c for c in d["callsign"]] == [None if pd.isna(c) else c.strip() for c in given]
    np.testing.assert_array_equal(d["nacp"], reports["nacp"])
    moving = np.isfinite(reports["vx"].to_numpy())
    assert (np.isfinite(d["vx"]) == moving).all()
    # ground speed 2^-14 NM/s and track 360/2^16 deg at up to 425 m/s: well under 0.1 m/s
    speed_error = np.hypot(d["vx"] - reports["vx"], d["vy"] - reports["vy"])
    climbing = np.isfinite(reports["vz"].to_numpy())
    assert speed_error[climbing].max() < 0.1
    # without a vertical rate the aircraft's vertical part of an origin-frame velocity (up to 2 deg away) is lost
    assert speed_error[moving & ~climbing].max() < np.hypot(300, 300) * np.radians(np.hypot(2, 2)) ** 2
    assert np.abs(d["vz"] - reports["vz"])[climbing].max() < 0.1


def test_time_of_day_wraps_over_midnight(encoded):
    reports, _, d = encoded
    assert (d["time_of_day_s"] < 900).any() and (d["time_of_day_s"] > 86000).any()
    assert (np.diff(d["time"]) >= 0).all()


def test_sigma_m_becomes_the_nacp_whose_bound_holds_it():
    reports = pd.DataFrame({"time": [0.0] * 4, "icao24": ["a00001"] * 4, "lat": [1.0] * 4, "lon": [1.0] * 4,
                            "alt_m": [0.0] * 4, "sigma_m": [1.0, 4.0, 30.0 / c21.EPU95_PER_SIGMA, 1e5]})
    decoded, _ = decode_cat021(cat021_blocks(encode_cat021(reports, (1, 2))))
    # 1 m: EPU 2.45 m < 3 m (NACp 11); 4 m: 9.8 m < 10 m (10); EPU exactly 30 m (9); 100 km: none (0)
    assert decoded["nacp"].tolist() == [11, 10, 9, 0]


def test_alternative_items_and_skipped_items_decode_like_libasterix():
    """I021/073, 130, 145 and 155 in place of 071, 131, 140 and 157, with items read only for their size."""
    rec = CAT021.cv_record.create({
        "010": (("SAC", 7), ("SIC", 9)), "040": (1 << 4,), "161": (0, 1234), "015": 3, "073": 5 * 128 + 3,
        "130": (("LAT", -(1 << 22)), ("LON", (1 << 23) - 1)), "072": 77, "080": 0x123456, "145": -48,
        "090": (0x12,), "210": (0, 0, 2, 0), "155": (("RE", 0), ("BVR", -100)), "170": callsign_code("KLM9"),
        "220": {"WS": 1}, "110": {"TIS": (0,)}, "250": [0x1122334455667788], "295": {"AOS": 5, "M3A": 6},
    })
    data = CAT021.create([rec]).unparse().to_bytes()
    decoded, problems = decode_cat021(data, strict=True)
    row = decoded.iloc[0]
    assert problems.count == 0
    assert row["time_of_day_s"] == 5 + 3 / 128
    assert row["lat"] == -90.0 and row["lon"] == ((1 << 23) - 1) * c21.LAT_LON_LSB_DEG
    assert row["alt_m"] == pytest.approx(-12 * 100 * 0.3048)
    assert row["icao24"] == "123456" and row["callsign"] == "KLM9"
    assert np.isnan(row["nacp"])  # I021/090 without its first extension carries no NACp
    assert row["vertical_rate_mps"] == pytest.approx(-625 * 0.3048 / 60)


def test_framing_uap_matches_libasterix():
    uap = framing._UAP[21]
    spec_items = CAT021.cv_record.cv_items_list
    assert len(uap) == len(spec_items)
    kinds = {"Element": framing.FIXED, "Group": framing.FIXED, "Extended": framing.EXTENDED,
             "Repetitive": framing.REPETITIVE, "Explicit": framing.EXPLICIT, "Compound": framing.COMPOUND}
    for (name, kind, size, subs), item in zip(uap, spec_items):
        non_spare = getattr(item, "cv_non_spare", None)
        if non_spare is None:
            assert kind == 0
            continue
        variation = non_spare.cv_rule.cv_variation
        assert name == non_spare.cv_name
        assert kind == kinds[variation.__mro__[1].__name__]
        if kind == framing.FIXED:
            assert size * 8 == variation.cv_bit_size
        if kind == framing.COMPOUND:
            assert len(subs) == len(variation.cv_items_list)


def test_a_report_without_a_position_is_skipped_and_located():
    good = {"010": (("SAC", 1), ("SIC", 1)), "040": (1 << 4,), "071": 0, "080": 1, "140": 0,
            "131": (("LAT", 0), ("LON", 0))}
    bad = {k: v for k, v in good.items() if k != "131"}
    data = CAT021.create([CAT021.cv_record.create(good), CAT021.cv_record.create(bad),
                          CAT021.cv_record.create(good)]).unparse().to_bytes()
    decoded = decode_asterix(data)
    assert len(decoded.adsb["time"]) == 2
    (problem,) = decoded.problems.problems
    first_length = len(CAT021.cv_record.create(good).unparse().to_bytes())
    assert problem.kind == "record without I021/131 or 130" and problem.offset == 3 + first_length


def test_velocities_without_an_origin_are_an_error():
    reports = random_reports(4, seed=1)
    with pytest.raises(ValueError, match="origin"):
        encode_cat021(reports, (1, 2))

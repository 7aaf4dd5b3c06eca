"""sensors.json: round trip, defaults, extras, and one test per validation rule."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from skytrack.geo import SensorSet
from skytrack.io import InputError, read_sensors, write_sensors

FORMATS_EXAMPLE = {
    "format_version": "1",
    "epoch_utc": "2021-10-07T12:00:00Z",
    "origin": {"lat": 48.86, "lon": 2.50, "alt_m": 0.0},
    "sensors": [
        {
            "name": "radar1", "type": "radar-2d",
            "lat": 48.86, "lon": 2.50, "alt_m": 0.0, "x": 0.0, "y": 0.0, "z": 0.0,
            "north_offset_deg": 0.0, "scan_period_s": 4.0, "scan_phase_s": 0.0,
            "sigma_range_m": 40.0, "sigma_azimuth_deg": 0.07,
            "sigma_elevation_deg": None, "sigma_range_rate_mps": None,
            "max_range_m": 250000.0, "min_elevation_deg": 0.0,
            "p_detection": 0.9, "clutter_per_scan": 20.0,
        },
        {
            "name": "radar2", "type": "radar-3d", "x": 30000.0, "y": 1000.0, "scan_period_s": 6.0,
            "sigma_range_m": 50.0, "sigma_azimuth_deg": 0.1, "sigma_elevation_deg": 0.2,
        },
        {"name": "adsb", "type": "adsb"},
    ],
}  # fmt: skip


def _write(tmp_path, data, name="sensors.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def test_formats_example_reads(tmp_path):
    sensors = read_sensors(_write(tmp_path, FORMATS_EXAMPLE))
    assert isinstance(sensors, SensorSet)
    assert sensors.names == ["radar1", "radar2", "adsb"]
    assert sensors.epoch_utc == "2021-10-07T12:00:00Z"
    assert (sensors.origin.lat, sensors.origin.lon, sensors.origin.alt_m) == (48.86, 2.5, 0.0)
    radar1 = sensors["radar1"]
    assert radar1.sigma_range_m == 40.0 and radar1.sigma_elevation_deg is None and radar1.p_detection == 0.9
    np.testing.assert_allclose(sensors["radar2"].position, [30000.0, 1000.0, 0.0])


def test_round_trip_keeps_everything(tmp_path, sensor_set):
    path = write_sensors(sensor_set, tmp_path / "deep" / "dir" / "sensors.json")
    back = read_sensors(path)
    assert back.to_dict() == sensor_set.to_dict()
    assert back["radar2"].extra == {"vendor": "acme", "platform": {"file": "carrier.parquet"}}
    np.testing.assert_allclose(back["radar2"].position, sensor_set["radar2"].position)
    np.testing.assert_allclose(back["radar1"].rotation, sensor_set["radar1"].rotation)
    # and a second round trip is byte-identical
    again = write_sensors(back, tmp_path / "again.json")
    assert again.read_text() == path.read_text()


def test_top_level_defaults_and_per_sensor_override(tmp_path):
    data = copy.deepcopy(FORMATS_EXAMPLE)
    data.update({"scan_period_s": 5.0, "p_detection": 0.8, "clutter_per_scan": 3.0, "site": "CDG"})
    del data["sensors"][1]["scan_period_s"]
    data["sensors"][1]["p_detection"] = 0.95
    data["sensors"][1]["clutter_per_scan"] = None  # null = not given: the default applies
    sensors = read_sensors(_write(tmp_path, data))
    assert sensors["radar1"].scan_period_s == 4.0  # per-sensor value wins
    assert sensors["radar2"].scan_period_s == 5.0  # default
    assert sensors["radar2"].p_detection == 0.95
    assert sensors["radar2"].clutter_per_scan == 3.0
    assert sensors.extra == {"site": "CDG"}


def test_unknown_keys_are_kept(tmp_path):
    data = copy.deepcopy(FORMATS_EXAMPLE)
    data["sensors"][0]["antenna"] = {"gain_db": 34}
    data["notes"] = ["x"]
    sensors = read_sensors(_write(tmp_path, data))
    assert sensors["radar1"].extra == {"antenna": {"gain_db": 34}}
    assert sensors.extra == {"notes": ["x"]}
    back = read_sensors(write_sensors(sensors, tmp_path / "out.json"))
    assert back["radar1"].extra == {"antenna": {"gain_db": 34}} and back.extra == {"notes": ["x"]}


def _mutate(path_keys, value):
    data = copy.deepcopy(FORMATS_EXAMPLE)
    target = data
    for key in path_keys[:-1]:
        target = target[key]
    if value is KeyError:
        del target[path_keys[-1]]
    else:
        target[path_keys[-1]] = value
    return data


S0 = "sensors[0] ('radar1')"
S1 = "sensors[1] ('radar2')"

# (where to change, new value, expected message after "sensors.json: ")
CASES = [
    (["format_version"], "2", 'format_version must be version 1 ("1", 1, "1.0" or "1.x"), got "2"'),
    (["format_version"], 2, 'format_version must be version 1 ("1", 1, "1.0" or "1.x"), got 2'),
    (["format_version"], True, 'format_version must be version 1 ("1", 1, "1.0" or "1.x"), got True'),
    (["format_version"], "1.", 'format_version must be version 1 ("1", 1, "1.0" or "1.x"), got "1."'),
    (["format_version"], KeyError, 'format_version is missing (expected "1")'),
    (["epoch_utc"], "noon", "epoch_utc 'noon' is not a timestamp"),
    (["origin"], KeyError, "origin is missing (it gives the lat/lon/alt_m of the ENU frame)"),
    (["origin", "lat"], 91.0, "origin: lat must be in [-90, 90], got 91"),
    (["origin", "lon"], -181.0, "origin: lon must be in [-180, 180], got -181"),
    (["origin", "lon"], KeyError, "origin: lon is missing"),
    (["origin", "alt_m"], "high", 'origin: alt_m must be a number, got "high"'),
    (["sensors"], {}, "sensors must be a list, got {}"),
    (["sensors", 1, "name"], KeyError, "sensors[1]: name must be a non-empty string, got None"),
    (["sensors", 1, "name"], "radar1", "sensors[1] ('radar1'): name repeats sensors[0]"),
    (
        ["sensors", 1, "type"],
        "sonar",
        f'{S1}: type must be one of radar-2d, radar-3d, radar-airborne, adsb, got "sonar"',
    ),
    (["sensors", 1, "sigma_range_m"], -3, f"{S1}: sigma_range_m must be in (0, 1e+05], got -3"),
    (["sensors", 1, "sigma_range_m"], 0.0, f"{S1}: sigma_range_m must be in (0, 1e+05], got 0"),
    (["sensors", 1, "sigma_azimuth_deg"], "0.1", f'{S1}: sigma_azimuth_deg must be a number, got "0.1"'),
    (["sensors", 1, "sigma_elevation_deg"], -0.2, f"{S1}: sigma_elevation_deg must be in (0, 45], got -0.2"),
    (["sensors", 0, "sigma_range_rate_mps"], -1, f"{S0}: sigma_range_rate_mps must be in (0, 1e+04], got -1"),
    (["sensors", 0, "scan_period_s"], 0, f"{S0}: scan_period_s must be in [0.001, 3600], got 0"),
    # fuzz suite: a denormal period passed the old (0, 3600] rule and overflowed the tracker's output clock
    (["sensors", 0, "scan_period_s"], 1e-320, f"{S0}: scan_period_s must be in [0.001, 3600], got 9.99989e-321"),
    (["sensors", 0, "p_detection"], 1.2, f"{S0}: p_detection must be in [0, 1], got 1.2"),
    (["sensors", 0, "clutter_per_scan"], -0.5, f"{S0}: clutter_per_scan must be in [0, 1e+07], got -0.5"),
    (["sensors", 0, "max_range_m"], 0, f"{S0}: max_range_m must be in (0, 1e+07], got 0"),
    (["sensors", 0, "lat"], 100.0, f"{S0}: lat must be in [-90, 90], got 100"),
    (["sensors", 0, "north_offset_deg"], True, f"{S0}: north_offset_deg must be a number, got True"),
    (["sensors", 0, "sigma_range_m"], KeyError, f"{S0}: sigma_range_m is required for a radar-2d sensor"),
    (["sensors", 0, "sigma_azimuth_deg"], None, f"{S0}: sigma_azimuth_deg is required for a radar-2d sensor"),
    (["sensors", 1, "sigma_elevation_deg"], KeyError, f"{S1}: sigma_elevation_deg is required for a radar-3d sensor"),
    (["sensors", 1, "x"], KeyError, f"{S1}: position unknown: give lat and lon, or x and y"),
    (
        ["sensors", 0, "scan_period_s"],
        KeyError,
        f"{S0}: scan_period_s is required for a radar-2d sensor (the antenna's revolution period, per sensor or "
        "at the top level)",
    ),
    (["sensors", 1, "scan_period_s"], None, f"{S1}: scan_period_s is required for a radar-3d sensor (the antenna's "
                                            "revolution period, per sensor or at the top level)"),
    (["sensors", 0, "sigma_range_m"], 1e300, f"{S0}: sigma_range_m must be in (0, 1e+05], got 1e+300"),
    (["sensors", 0, "sigma_azimuth_deg"], 90.0, f"{S0}: sigma_azimuth_deg must be in (0, 45], got 90"),
    (["origin", "alt_m"], 1e7, "origin: alt_m must be in [-1e+04, 1e+06], got 10000000"),
    (["sensors", 0, "max_range_m"], 10**400, f"{S0}: max_range_m is out of range (an integer of about 401 digits)"),
]


@pytest.mark.parametrize("keys, value, message", CASES)
def test_validation_errors_name_file_sensor_and_key(tmp_path, keys, value, message):
    path = _write(tmp_path, _mutate(keys, value))
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert str(info.value) == f"{path}: {message}"
    assert info.value.file == str(path)


def test_key_attribute_of_a_sensor_error(tmp_path):
    path = _write(tmp_path, _mutate(["sensors", 1, "sigma_range_m"], -3))
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert (info.value.where, info.value.key) == (S1, "sigma_range_m")


def test_inconsistent_positions_name_the_sensor(tmp_path):
    path = _write(tmp_path, _mutate(["sensors", 0, "x"], 5000.0))
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert str(info.value).startswith(
        f"{path}: {S0}: sensor 'radar1': x/y/z [5000.0, 0.0, 0.0] disagree with lat/lon/alt_m"
    )


def test_broken_json_names_line(tmp_path):
    path = tmp_path / "sensors.json"
    path.write_text('{\n  "format_version": "1",\n  "origin": {"lat": 48.86,, "lon": 2.5}\n}\n')
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert info.value.line == 3
    assert str(info.value).startswith(f"{path}, line 3: not valid JSON (Expecting property name")


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="sensors.json: file not found"):
        read_sensors(tmp_path / "sensors.json")


def test_write_refuses_invalid_sets(tmp_path, sensor_set):
    sensor_set["radar1"].p_detection = 2.0
    with pytest.raises(InputError) as info:
        write_sensors(sensor_set, tmp_path / "s.json")
    assert "p_detection must be in [0, 1], got 2" in str(info.value)
    assert not (tmp_path / "s.json").exists()


@pytest.mark.parametrize("version", ["1", 1, 1.0, "1.0", "1.3", " 1 "])
def test_every_spelling_of_version_one_reads(tmp_path, version):
    """Other tools write the version as a number or as "1.0": all are version 1, written back as "1"."""
    data = copy.deepcopy(FORMATS_EXAMPLE)
    data["format_version"] = version
    sensors = read_sensors(_write(tmp_path, data))
    assert sensors.format_version == "1"
    assert sensors.to_dict()["format_version"] == "1"


def test_scan_period_given_at_the_top_level_is_enough(tmp_path):
    data = copy.deepcopy(FORMATS_EXAMPLE)
    del data["sensors"][0]["scan_period_s"], data["sensors"][1]["scan_period_s"]
    data["scan_period_s"] = 5.0
    sensors = read_sensors(_write(tmp_path, data))
    assert sensors["radar1"].scan_period_s == sensors["radar2"].scan_period_s == 5.0


@pytest.mark.parametrize("text, message", [
    ('{"format_version": "1", "origin": {"lat": NaN, "lon": 2.5}, "sensors": []}',
     "not valid sensors JSON (NaN is not a number that sensors.json may hold)"),
    ('{"format_version": "1", "origin": {"lat": 1, "lon": -Infinity}, "sensors": []}',
     "not valid sensors JSON (-Infinity is not a number that sensors.json may hold)"),
    ("[" * 100_000 + "]" * 100_000, "not valid sensors JSON (nested too deeply)"),
])
def test_json_that_python_would_accept_or_crash_on_is_one_line_error(tmp_path, text, message):
    path = tmp_path / "sensors.json"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert str(info.value) == f"{path}: {message}"


def test_integer_literal_beyond_pythons_digit_limit_is_one_line_error(tmp_path):
    path = tmp_path / "sensors.json"
    path.write_text('{"format_version": "1", "origin": {"lat": 1, "lon": 2, "alt_m": ' + "9" * 5000 + '}, "sensors": []}')
    with pytest.raises(InputError) as info:
        read_sensors(path)
    assert str(info.value).startswith(f"{path}: not valid sensors JSON (Exceeds the limit (4300 digits)")

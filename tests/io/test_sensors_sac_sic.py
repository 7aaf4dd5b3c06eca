"""sensors.json ASTERIX identities (issue 11): optional integer ``sac``/``sic`` per sensor.

Read, written back, used by ``SensorSet.by_sac_sic``; bad values are errors naming the
sensor and key: outside [0, 255], not integers, one without the other, a pair repeated.
"""

from __future__ import annotations

import json

import pytest

from skytrack.geo.sensors import Origin, Sensor, SensorSet
from skytrack.io import InputError, read_sensors, write_sensors
from skytrack.io.sensors import sensor_set_from_dict


def _file(*sensors: dict, **top) -> dict:
    return {"format_version": "1", "origin": {"lat": 47.0, "lon": 8.0}, **top,
            "sensors": [{"name": f"r{i}", "type": "radar-2d", "lat": 47.0, "lon": 8.0, "sigma_range_m": 50.0,
                         "sigma_azimuth_deg": 0.1, "scan_period_s": 4.0, **s} for i, s in enumerate(sensors)]}


def test_sac_sic_read_written_and_looked_up(tmp_path):
    data = _file({"sac": 25, "sic": 0}, {"sac": 25, "sic": 255}, {})
    sensors = sensor_set_from_dict(data)
    assert sensors.by_sac_sic() == {(25, 0): "r0", (25, 255): "r1"}
    path = write_sensors(sensors, tmp_path / "sensors.json")
    written = json.loads(path.read_text())["sensors"]
    assert [(s.get("sac"), s.get("sic")) for s in written] == [(25, 0), (25, 255), (None, None)]
    assert read_sensors(path).by_sac_sic() == sensors.by_sac_sic()


def test_a_top_level_sac_is_every_sensors_default():
    sensors = sensor_set_from_dict(_file({"sic": 1}, {"sic": 2}, sac=7))
    assert sensors.by_sac_sic() == {(7, 1): "r0", (7, 2): "r1"}


@pytest.mark.parametrize("values, message", [
    ({"sac": 256, "sic": 1}, "sensors[0] ('r0'): sac must be in [0, 255] (an ASTERIX octet), got 256"),
    ({"sac": 1, "sic": -1}, "sensors[0] ('r0'): sic must be in [0, 255] (an ASTERIX octet), got -1"),
    ({"sac": 1.0, "sic": 1}, "sensors[0] ('r0'): sac must be an integer in [0, 255] (ASTERIX), got 1"),
    ({"sac": "1", "sic": 1}, 'sensors[0] (\'r0\'): sac must be an integer in [0, 255] (ASTERIX), got "1"'),
    ({"sac": 1, "sic": False}, "sensors[0] ('r0'): sic must be an integer in [0, 255] (ASTERIX), got False"),
    ({"sac": 1}, "sensors[0] ('r0'): sic is missing: an ASTERIX source is named by sac and sic together"),
    ({"sic": 1}, "sensors[0] ('r0'): sac is missing"),
])
def test_bad_sac_sic_name_the_sensor(values, message):
    with pytest.raises(InputError) as error:
        sensor_set_from_dict(_file(values))
    assert message in str(error.value)


def test_a_repeated_pair_is_an_error_naming_both_sensors():
    with pytest.raises(InputError, match=r"sensors\[2\] \('r2'\): sac/sic 3/4 repeats sensors\[0\]"):
        sensor_set_from_dict(_file({"sac": 3, "sic": 4}, {"sac": 3, "sic": 5}, {"sac": 3, "sic": 4}))
    with pytest.raises(ValueError, match="repeated: 3/4"):
        SensorSet(Origin(0.0, 0.0), [Sensor("a", "adsb", sac=3, sic=4), Sensor("b", "adsb", sac=3, sic=4)])

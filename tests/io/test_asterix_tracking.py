"""Issue 11 acceptance: ASTERIX recordings track like the Parquet plots they encode.

Two minutes of the bundled ``adsb_identification`` scenario (one 4 s radar, clutter, 25
aircraft, 20 with ADS-B) are simulated; the plots are quantised to the ASTERIX resolutions
(1/128 s, 1/256 NM, 360/2^16 deg, 25 ft) and written three ways:

- quantised Parquet (the reference run);
- (a) skytrack's ``encode_asterix`` (CAT048 + CAT034 north markers) + ``encode_cat021``;
- (b) libasterix's own encoder driven here record by record (not through skytrack), with
  other block sizes and one TYP for every plot;

and all are tracked by ``run_tracking``.  The tracks must be the same rows (the decoded
values are the quantised ones exactly), so GOSPA against the truth is the same (the
acceptance asks for 1 %).  The ADS-B reports given as CAT021 label the same tracks as the
Parquet reports quantised alike (NACp in place of sigma_m).  Also: a pcap capture of (a)
tracks the same; sensors by SAC/SIC, unknown SAC/SIC, time of day past midnight, north
markers setting the scan phase, damage located by byte offset in .ast and .pcap files.
"""

from __future__ import annotations

import asterix.generated as gen
import numpy as np
import pandas as pd
import pytest
from io_samples import split_blocks

from skytrack.analysis import evaluate
from skytrack.app.run import run_tracking
from skytrack.app.simulate import run_simulation
from skytrack.io import (
    InputError,
    ReadReport,
    read_plots,
    read_tracks,
    write_adsb,
    write_plots,
    write_sensors,
)
from skytrack.io.adsb import nacp_sigma_m, read_adsb
from skytrack.io.asterix import encode_asterix
from skytrack.io.asterix import units as u
from skytrack.io.asterix.cat021 import cat021_blocks, encode_cat021, sigma_to_nacp
from skytrack.io.asterix.pcap import write_pcap
from skytrack.io.asterix.reading import read_asterix_input, seconds_since_epoch

EPOCH_TIME_OF_DAY = 12 * 3600.0  # the scenario's epoch_utc is 2021-10-07T12:00:00Z
ADSB_STATION = (0, 101)
PLOT_COLUMNS = ["time", "sensor", "range_m", "azimuth_deg", "mode3a", "mode_c_ft", "mode_s"]


def quantise(plots: pd.DataFrame) -> pd.DataFrame:
    q = plots[PLOT_COLUMNS].copy()
    q["time"] = np.rint(q["time"] / u.TIME_LSB_S) * u.TIME_LSB_S
    q["range_m"] = np.rint(q["range_m"] / u.RHO_LSB_M) * u.RHO_LSB_M
    q["azimuth_deg"] = np.mod(np.rint(q["azimuth_deg"] / u.THETA_LSB_DEG), 65536) * u.THETA_LSB_DEG
    q["mode_c_ft"] = np.rint(q["mode_c_ft"] / u.FLIGHT_LEVEL_LSB_FT) * u.FLIGHT_LEVEL_LSB_FT
    return q


def north_marker_frame(sensors, end_s: float) -> pd.DataFrame:
    rows = []
    for s in sensors.sensors:
        if s.is_radar:
            times = s.scan_phase_s + s.scan_period_s * np.arange(0, int(end_s / s.scan_period_s) + 1)
            rows.append(pd.DataFrame({"time": times, "sensor": s.name, "message": "north_marker"}))
    return pd.concat(rows, ignore_index=True)


def libasterix_recording(plots: pd.DataFrame, markers: pd.DataFrame, sac_sic: dict) -> bytes:
    """CAT048 / CAT034 written with libasterix directly (test (b)): blocks of 50 records."""
    cat048, cat034 = gen.Cat_048_1_32, gen.Cat_034_1_29

    def tod(t):
        return int(round((EPOCH_TIME_OF_DAY + t) % 86400 * 128)) % (86400 * 128)

    entries = []
    for t, name in zip(markers["time"], markers["sensor"]):
        sac, sic = sac_sic[name]
        entries.append((t, 0, cat034, cat034.cv_record.create({"000": 1, "010": (("SAC", sac), ("SIC", sic)),
                                                                  "030": tod(t)})))
    for row in plots.itertuples(index=False):
        sac, sic = sac_sic[row.sensor]
        items = {"010": (("SAC", sac), ("SIC", sic)), "140": tod(row.time), "020": (3 << 4,),
                 "040": (("RHO", int(round(row.range_m / (1852 / 256)))),
                         ("THETA", int(round(row.azimuth_deg / (360 / 65536))) % 65536))}
        if isinstance(row.mode3a, str):
            items["070"] = (0, 0, 0, 0, ("MODE3A", int(row.mode3a, 8)))
        if np.isfinite(row.mode_c_ft):
            items["090"] = (0, 0, ("FL", int(round(row.mode_c_ft / 25))))
        if isinstance(row.mode_s, str):
            items["220"] = int(row.mode_s, 16)
        entries.append((row.time, 1, cat048, cat048.cv_record.create(items)))
    entries.sort(key=lambda e: (e[0], e[1]))
    out, k = [], 0
    while k < len(entries):
        spec, run = entries[k][2], []
        while k < len(entries) and entries[k][2] is spec and len(run) < 50:
            run.append(entries[k][3])
            k += 1
        out.append(spec.create(run).unparse().to_bytes())
    return b"".join(out)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    out = tmp_path_factory.mktemp("asterix_tracking")
    result = run_simulation("adsb_identification", duration=120.0)
    sensors = result.sensors
    for k, sensor in enumerate(sensors.sensors):
        sensor.sac, sensor.sic = 25, k + 1
        sensor.scan_phase_s = 1.25  # the markers must say so: the plots' own phase is the simulated one
    sac_sic = {name: pair for pair, name in sensors.by_sac_sic().items()}
    write_sensors(sensors, out / "sensors.json")
    plots = quantise(result.plots)
    write_plots(plots, out / "plots.parquet", sensors=sensors)
    adsb = result.adsb.copy()
    adsb["nacp"] = sigma_to_nacp(adsb["sigma_m"].to_numpy()).astype(float)
    adsb["sigma_m"] = nacp_sigma_m(adsb["nacp"])  # what CAT021 carries: the NACp bound
    write_adsb(adsb, out / "adsb.parquet", origin=sensors.origin)
    markers = north_marker_frame(sensors, float(plots["time"].max()))
    ours = encode_asterix(plots, sac_sic, service=markers, time_of_day_at_epoch_s=EPOCH_TIME_OF_DAY)
    ours_adsb = cat021_blocks(encode_cat021(adsb, ADSB_STATION, time_of_day_at_epoch_s=EPOCH_TIME_OF_DAY,
                                            origin=sensors.origin))
    (out / "ours.ast").write_bytes(ours + ours_adsb)
    (out / "theirs.ast").write_bytes(libasterix_recording(plots, markers, sac_sic))
    (out / "ours.pcap").write_bytes(write_pcap(split_blocks(ours + ours_adsb)))
    runs = {}
    for name, plots_file, adsb_file in [("parquet", "plots.parquet", "adsb.parquet"), ("ours", "ours.ast", "ours.ast"),
                                        ("theirs", "theirs.ast", "adsb.parquet"), ("pcap", "ours.pcap", "ours.pcap")]:
        summary = run_tracking(out / plots_file, out / "sensors.json", out / f"tracks_{name}.parquet",
                               adsb_path=out / adsb_file)
        runs[name] = (summary, read_tracks(out / f"tracks_{name}.parquet"))
    return out, result, plots, runs


def _gospa(tracks, truth) -> float:
    return float(evaluate(tracks, truth).summary["gospa_mean_m"])


@pytest.mark.parametrize("name", ["ours", "theirs", "pcap"])
def test_asterix_recordings_track_like_the_quantised_parquet_plots(recordings, name):
    _, result, plots, runs = recordings
    reference_summary, reference = runs["parquet"]
    summary, tracks = runs[name]
    assert summary.plots == reference_summary.plots == len(plots)
    assert len(reference) > 500
    kinematic = ["time", "track_id", "x", "y", "z", "vx", "vy", "vz", "var_x", "var_y", "status"]
    pd.testing.assert_frame_equal(tracks[kinematic], reference[kinematic])
    reference_gospa = _gospa(reference, result.truth)
    assert abs(_gospa(tracks, result.truth) - reference_gospa) <= 0.01 * reference_gospa


def test_cat021_reports_label_the_tracks_like_the_parquet_reports(recordings):
    _, _, _, runs = recordings
    labels = {}
    for name in ("parquet", "ours", "pcap"):
        summary, tracks = runs[name]
        assert summary.identification["adsb_reports"] == runs["parquet"][0].identification["adsb_reports"]
        labelled = tracks.dropna(subset=["icao24"]).groupby("track_id")["icao24"].last()
        labels[name] = labelled.to_dict()
    assert len(labels["parquet"]) >= 15
    assert labels["ours"] == labels["parquet"] == labels["pcap"]


def test_north_markers_set_the_scan_phase(recordings):
    out, _, _, _ = recordings
    from skytrack.io import read_sensors

    sensors = read_sensors(out / "sensors.json")
    sensors.sensors[0].scan_phase_s = 3.0
    report = ReadReport(file="ours.ast")
    decoded = read_asterix_input(out / "ours.ast", sensors, lenient=True, report=report)
    assert decoded.north_marker_phase_s == {"radar1": pytest.approx(1.25, abs=1e-9)}
    assert sensors.sensors[0].scan_phase_s == pytest.approx(1.25, abs=1e-9)
    assert any("north markers put the beam north at 1.250 s" in w for w in report.warnings)


def test_unknown_sac_sic_is_an_error_naming_it_and_its_first_offset(recordings, tmp_path):
    out, _, plots, _ = recordings
    from skytrack.io import read_sensors

    sensors = read_sensors(out / "sensors.json")
    data = (out / "ours.ast").read_bytes()
    stranger = encode_asterix(plots.iloc[:3].assign(sensor="x"), {"x": (7, 8)}, time_of_day_at_epoch_s=EPOCH_TIME_OF_DAY)
    path = tmp_path / "mixed.ast"
    path.write_bytes(data + stranger)
    with pytest.raises(InputError, match=rf"mixed.ast: byte offset {len(data) + 3}: 3 CAT048 plot\(s\) of SAC/SIC 7/8 "
                                         r"\(the first at this offset\): no sensor of sensors.json has that pair "
                                         r"\(it has: radar1 25/1\)"):
        read_plots(path, sensors)
    frame, report = read_plots(path, sensors, lenient=True)
    assert len(frame) == len(plots)
    assert report.skipped["unknown SAC/SIC (CAT048 plots)"].count == 3


def test_damage_is_located_in_the_ast_and_pcap_files(recordings, tmp_path):
    out, _, plots, _ = recordings
    from skytrack.io import read_sensors

    sensors = read_sensors(out / "sensors.json")
    blocks = split_blocks((out / "ours.ast").read_bytes())
    bad = bytearray(blocks[5])
    bad[0] = 99  # unknown category
    damaged = blocks[:5] + [bytes(bad)] + blocks[6:]
    at = sum(len(b) for b in blocks[:5])
    (tmp_path / "d.ast").write_bytes(b"".join(damaged))
    with pytest.raises(InputError, match=rf"d.ast: byte offset {at}: ASTERIX \(block 5\): unknown category: category 99"):
        read_plots(tmp_path / "d.ast", sensors)
    capture = write_pcap(damaged)
    (tmp_path / "d.pcap").write_bytes(capture)
    file_offset = capture.index(bytes(bad))
    with pytest.raises(InputError, match=rf"d.pcap: byte offset {file_offset}: ASTERIX \(block 5\): unknown category"):
        read_plots(tmp_path / "d.pcap", sensors)
    frame, report = read_plots(tmp_path / "d.pcap", sensors, lenient=True)
    assert report.skipped["ASTERIX unknown category"].count == 1
    assert len(frame) == len(plots) - _records_of(blocks[5], 48)


def _records_of(block: bytes, category: int) -> int:
    from skytrack.io.asterix import decode_asterix

    decoded = decode_asterix(block)
    return decoded.plots["time"].size if category == 48 else decoded.service["time"].size


def test_time_of_day_past_midnight_and_before_the_epoch():
    # a source whose first message is just after midnight, epoch late the evening before: the next day
    t = seconds_since_epoch(np.array([10.0, 20.0]), np.array([1, 1]), 86390.0)
    np.testing.assert_array_equal(t, [20.0, 30.0])
    # a source starting up to 12 h before the epoch's time of day: negative times, same day
    t = seconds_since_epoch(np.array([3600.0, 86400.0 + 60.0]), np.array([2, 2]), 7200.0)
    np.testing.assert_array_equal(t, [-3600.0, 86400.0 + 60.0 - 7200.0])


def test_cat021_reports_read_as_adsb_with_time_since_epoch(recordings):
    out, result, _, _ = recordings
    from skytrack.io import read_sensors

    sensors = read_sensors(out / "sensors.json")
    adsb = read_adsb(out / "ours.ast", sensors=sensors)
    assert adsb.attrs["layout"] == "asterix"
    assert len(adsb) == len(result.adsb)
    expected = result.adsb.sort_values(["time"], kind="stable")
    assert np.abs(np.sort(adsb["time"].to_numpy()) - np.sort(expected["time"].to_numpy())).max() <= u.TIME_LSB_S / 2
    assert set(adsb["icao24"]) == set(result.adsb["icao24"])

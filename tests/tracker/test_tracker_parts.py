"""Tracker building blocks: configuration checks, the structure-of-arrays track bank, plot
batches, beam phase and beam-crossing times (skytrack.tracker.config / bank / schedule,
skytrack.core.plots)."""

import numpy as np
import pandas as pd
import pytest

from skytrack.geo.sensors import Sensor, SensorSet
from skytrack.models.motion import ConstantVelocityAxis, SingerAxisModel
from skytrack.core.plots import FT_TO_M, PlotBatch
from skytrack.filters.kalman import KalmanFilter
from skytrack.models.motion import constant_velocity
from skytrack.tracker.bank import CONFIRMED, TENTATIVE, TrackBank
from skytrack.tracker.config import TrackerConfig
from skytrack.tracker.schedule import beam_crossing_time, check_time_order, estimate_beam_phase
from skytrack.tracker.tracker import Tracker
from skytrack.sim import load_scenario, simulate

# ----------------------------------------------------------------------------- configuration


@pytest.mark.parametrize("kwargs, message", [
    (dict(model="imm"), "model must be one of"),
    (dict(init="three-point"), "init must be one of"),
    (dict(discretization="exactish"), "discretization"),
    (dict(p_gate=1.0), "p_gate must be in"),
    (dict(p_gate=0.0), "p_gate must be in"),
    (dict(gate_threshold=0.0), "gate_threshold must be > 0"),
    (dict(confirm_m=5, confirm_n=4), "confirm_m <= confirm_n"),
    (dict(confirm_m=0), "1 <= confirm_m"),
    (dict(confirm_n=33, confirm_m=3), "<= 32"),
    (dict(delete_misses=0), "delete_misses must be >= 1"),
    (dict(tracking_dim=1), "tracking_dim must be 2, 3 or None"),
    (dict(init_sigma_v=-1.0), "init_sigma_v must be finite and > 0"),
    (dict(window_s=np.inf), "window_s must be finite and > 0"),
    (dict(cv_q=-0.1), "cv_q must be finite and >= 0"),
    (dict(singer_sigma_a=np.nan), "singer_sigma_a must be finite and >= 0"),
    (dict(manoeuvre_q_scale=0.5), "manoeuvre_q_scale must be >= 1"),
    (dict(manoeuvre_memory=1.0), "manoeuvre_memory must be in"),
    (dict(manoeuvre_on_nis=1.0, manoeuvre_off_nis=2.0), "manoeuvre_off_nis <= manoeuvre_on_nis"),
    (dict(sectors_per_scan=0), "sectors_per_scan must be >= 1"),
    (dict(output_interval_s=0.0), "output_interval_s must be > 0"),
])
def test_config_rejects_bad_values(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrackerConfig(**kwargs)


def test_config_motion_models():
    cv = TrackerConfig(model="cv", cv_q=2.5).motion_model(2)
    assert cv.dim == 4 and cv.axes[0] == ConstantVelocityAxis(2.5)
    singer = TrackerConfig(model="singer", singer_tau_s=30.0, singer_sigma_a=3.0, discretization="paper").motion_model(3)
    assert singer.dim == 9 and singer.axes[2] == SingerAxisModel(30.0, 3.0, "paper")
    assert TrackerConfig().to_dict(flat=True)["confirm_m"] == 3
    assert TrackerConfig().to_dict()["lifecycle"]["confirm_m"] == 3


def test_config_nested_form_round_trips_and_names_bad_keys(tmp_path):
    config = TrackerConfig(confirm_m=2, confirm_n=3, model="singer", p_gate=0.99, init="two-point")
    assert config.lifecycle.confirm_m == 2 and config.motion.model == "singer" and config.initiation.method == "two-point"
    assert TrackerConfig.from_dict(config.to_dict()) == config
    path = tmp_path / "tracker.yaml"
    path.write_text("lifecycle:\n  confirm_m: 2\n  confirm_n: 3\nfilter:\n  kind: imm\n")
    loaded = TrackerConfig.from_file(path)
    assert loaded.confirm_m == 2 and loaded.filter.kind == "imm"
    json_path = tmp_path / "tracker.json"
    json_path.write_text('{"association": {"p_gate": 0.99}}')
    assert TrackerConfig.from_file(json_path).p_gate == 0.99
    path.write_text("lifecycle:\n  confirm_k: 2\n")
    with pytest.raises(ValueError, match=r"section lifecycle: unknown key\(s\) \['confirm_k'\]"):
        TrackerConfig.from_file(path)
    path.write_text("tracking:\n  x: 1\n")
    with pytest.raises(ValueError, match="unknown section"):
        TrackerConfig.from_file(path)
    path.write_text("lifecycle:\n  confirm_m: 5\n")
    with pytest.raises(ValueError, match="section lifecycle: need 1 <= confirm_m <= confirm_n"):
        TrackerConfig.from_file(path)
    with pytest.raises(ValueError, match="unknown tracker setting 'confirmm'"):
        TrackerConfig(confirmm=2)


def test_gate_threshold_is_the_chi_square_quantile(sim, radar1):
    """Spec 000 TV12: P_G = 0.99 gives chi^2_2 = 9.21034037197618, chi^2_3 = 11.344866730144373."""
    tracker = Tracker(sim.sensor_set([radar1]), TrackerConfig(p_gate=0.99))
    assert tracker.gate(2) == pytest.approx(9.21034037197618, rel=1e-12)
    assert tracker.gate(3) == pytest.approx(11.344866730144373, rel=1e-12)
    fixed = Tracker(sim.sensor_set([radar1]), TrackerConfig(gate_threshold=16.0))
    assert fixed.gate(2) == fixed.gate(4) == 16.0


def test_tracker_refuses_sensor_sets_it_cannot_use(sim, radar1):
    adsb_only = SensorSet(sim.ORIGIN, [Sensor("adsb", type="adsb")])
    with pytest.raises(ValueError, match="no radar"):
        Tracker(adsb_only)
    with pytest.raises(ValueError, match="'radar1'.*sigma_range_m and sigma_azimuth_deg"):
        Tracker(sim.sensor_set([radar1], sigma_range_m=None))
    three_d = sim.Radar(**{**radar1.__dict__, "type": "radar-3d"})
    with pytest.raises(ValueError, match="'radar1' is radar-3d but has no sigma_elevation_deg"):
        Tracker(sim.sensor_set([three_d]))


def test_tracking_dimension_follows_the_radars(sim, radar1):
    three_d = sim.Radar(**{**radar1.__dict__, "name": "r3", "type": "radar-3d", "sigma_elevation_deg": 0.2})
    assert Tracker(sim.sensor_set([radar1])).dim == 2
    assert Tracker(sim.sensor_set([three_d])).dim == 3
    assert Tracker(sim.sensor_set([radar1, three_d])).dim == 2
    assert Tracker(sim.sensor_set([radar1]), TrackerConfig(tracking_dim=3)).dim == 3


# ----------------------------------------------------------------------------- track bank


def test_bank_append_defaults_and_keep():
    kalman = KalmanFilter(constant_velocity(2, 1.0))
    bank = TrackBank(kalman)
    assert len(bank) == 0
    bank.append(kalman.initiate(np.arange(8.0).reshape(2, 4), np.broadcast_to(np.eye(4), (2, 4, 4))),
                t=np.array([1.0, 2.0]), track_id=np.array([7, 8]), status=TENTATIVE, mode3a=np.array([0o1234, -1]))
    bank.append(kalman.initiate(np.ones((1, 4)), np.eye(4)[None]), t=np.array([3.0]), track_id=np.array([9]),
                status=CONFIRMED)
    assert len(bank) == 3
    np.testing.assert_array_equal(bank.track_id, [7, 8, 9])
    np.testing.assert_array_equal(bank.status, [TENTATIVE, TENTATIVE, CONFIRMED])
    assert bank.track_id.dtype == np.int64 and bank.hit_bits.dtype == np.uint32
    assert np.isnan(bank.alt_m).all() and np.isnan(bank.confirmed_at).all()  # NaN defaults
    np.testing.assert_array_equal(bank.n_updates, [0, 0, 0])
    np.testing.assert_array_equal(bank.mode3a, [0o1234, -1, -1])  # -1: unknown
    bank.keep(np.array([True, False, True]))
    np.testing.assert_array_equal(bank.track_id, [7, 9])
    np.testing.assert_array_equal(bank.estimate().x, [[0.0, 1.0, 2.0, 3.0], [1.0, 1.0, 1.0, 1.0]])
    assert bank.estimate().P.shape == (2, 4, 4)
    np.testing.assert_array_equal(bank.mode3a, [0o1234, -1])
    bank.append(kalman.initiate(np.zeros((0, 4)), np.zeros((0, 4, 4))))  # appending nothing is a no-op
    assert len(bank) == 2


def test_bank_registered_columns_and_checkpoint_round_trip():
    kalman = KalmanFilter(constant_velocity(2, 1.0))
    bank = TrackBank(kalman)
    bank.register_column("identity_score", np.float64, 0.5)
    bank.append(kalman.initiate(np.arange(8.0).reshape(2, 4), np.broadcast_to(np.eye(4), (2, 4, 4))),
                track_id=np.array([1, 2]), identity_score=np.array([1.5, 2.5]))
    bank.append(kalman.initiate(np.ones((1, 4)), np.eye(4)[None]), track_id=np.array([3]))
    np.testing.assert_array_equal(bank.identity_score, [1.5, 2.5, 0.5])
    with pytest.raises(ValueError, match="exists already"):
        bank.register_column("identity_score", np.float64, 0.0)
    with pytest.raises(ValueError, match="no column"):
        bank.append(kalman.initiate(np.ones((1, 4)), np.eye(4)[None]), unknown=1)
    saved = bank.to_arrays()
    other = TrackBank(kalman)
    other.register_column("identity_score", np.float64, 0.5)
    other.load_arrays(saved)
    for name, values in other.to_arrays().items():
        np.testing.assert_array_equal(values, saved[name])


# ----------------------------------------------------------------------------- plot columns


def test_plot_columns_units_and_optional_columns(sim, radar1):
    sensors = sim.sensor_set([radar1])
    frame = pd.DataFrame({
        "time": [0.5, 1.0], "sensor": ["radar1", "radar1"], "range_m": [1000.0, 2000.0],
        "azimuth_deg": [90.0, 180.0], "mode_c_ft": [10000.0, None], "mode3a": ["7000", None],
        "elevation_deg": [1.0, np.nan],
    })
    plots = PlotBatch.from_frame(frame, sensors.names)
    np.testing.assert_allclose(plots.azimuth, [np.pi / 2, np.pi])
    np.testing.assert_allclose(plots.elevation, [np.radians(1.0), np.nan])
    np.testing.assert_allclose(plots.mode_c_m, [10000.0 * FT_TO_M, np.nan])
    assert FT_TO_M == 0.3048
    assert np.isnan(plots.range_rate).all() and plots.platform.shape == (2, 6) and np.isnan(plots.platform).all()
    np.testing.assert_array_equal(plots.mode3a, [0o7000, -1])
    np.testing.assert_array_equal(plots.iff, [-1, -1])
    np.testing.assert_array_equal(plots.sensor, [0, 0])
    np.testing.assert_array_equal(plots.row, [0, 1])
    both = PlotBatch.concat([plots, plots.take(np.array([1]))])
    assert len(both) == 3 and both.mode3a[2] == -1


def test_check_time_order_names_the_row_and_remembers_the_last_time(sim, radar1):
    sensors = sim.sensor_set([radar1])
    last = np.full(1, -np.inf)
    ok = PlotBatch.from_frame(pd.DataFrame({"time": [1.0, 2.0, 2.0], "sensor": "radar1", "range_m": 1.0,
                                            "azimuth_deg": 0.0}), sensors.names)
    check_time_order(ok, sensors, last)
    assert last[0] == 2.0
    later = PlotBatch.from_frame(pd.DataFrame({"time": [3.0, 1.5], "sensor": "radar1", "range_m": 1.0,
                                               "azimuth_deg": 0.0}), sensors.names)
    with pytest.raises(ValueError, match=r"myfile, row 1, column time: .*1\.500000 s after 3\.000000 s"):
        check_time_order(later, sensors, last, source="myfile")


@pytest.mark.parametrize("phase", [0.0, 1.3, 3.97, 0.02])
def test_estimate_beam_phase_recovers_the_phase(phase):
    """Plots at the beam-crossing times of random azimuths, with 0.05 deg azimuth noise;
    the phase is found modulo the period, including next to the wrap (3.97 s and 0.02 s)."""
    rng = np.random.default_rng(int(phase * 100))
    period = 4.0
    az = rng.uniform(0, 2 * np.pi, 60)
    time = phase + (rng.integers(0, 20, 60) + az / (2 * np.pi)) * period
    measured = np.remainder(az + np.radians(0.05) * rng.standard_normal(60), 2 * np.pi)
    estimate = estimate_beam_phase(time, measured, period)
    assert 0.0 <= estimate < period
    gap = (estimate - phase + period / 2) % period - period / 2
    assert abs(gap) < 3 * np.radians(0.05) / (2 * np.pi) * period / np.sqrt(60) + 1e-9


def test_beam_crossing_time():
    period, phase = 4.0, 1.0
    az = np.array([0.0, np.pi / 2, np.pi, 1.5 * np.pi])
    t = beam_crossing_time(az, phase, period, window_start=9.5)
    # the beam points at az at phase + (k + az / 2 pi) period: 9.0 + {0, 1, 2, 3} -> first >= 9.5
    np.testing.assert_allclose(t, [13.0, 10.0, 11.0, 12.0])
    assert np.all((t >= 9.5) & (t < 9.5 + period))


def test_plot_batch_parses_identity_codes_from_chunked_arrow_columns():
    """A pandas str column backed by several Arrow chunks (as read from large files) parses
    like a plain one: each code once, missing codes -1."""
    import pyarrow as pa

    chunked = pd.Series(pd.arrays.ArrowExtensionArray(
        pa.chunked_array([pa.array(["7000", None]), pa.array(["0123"])]))).astype("str")
    frame = pd.DataFrame({"time": [0.0, 1.0, 2.0], "sensor": "r", "range_m": 1.0, "azimuth_deg": 0.0,
                          "mode3a": chunked, "mode_s": ["4840d6", None, "4840D6"]})
    batch = PlotBatch.from_frame(frame, ["r"])
    np.testing.assert_array_equal(batch.mode3a, [0o7000, -1, 0o123])
    np.testing.assert_array_equal(batch.mode_s, [0x4840D6, -1, 0x4840D6])
    with pytest.raises(ValueError, match=r"row 1, column mode3a: '7g00' is not an octal code"):
        PlotBatch.from_frame(frame.assign(mode3a=["7000", "7g00", None]), ["r"])


@pytest.mark.parametrize("gap_s", [1e6, 1e11])
def test_a_long_gap_is_not_walked_a_window_at_a_time(gap_s):
    """A recording with a gap of days (or an absurd 1e11 s) tracks in the time of one without:
    once no track is alive the windows and output instants of the gap are skipped (1e6 s took
    16 s, 1e8 s would have taken half an hour); the tracks are those of the two halves.  The
    work is counted in windows, not timed (a fresh checkout also compiles the kernels here)."""
    result = simulate(load_scenario("crossing"))
    plots = result.plots.copy()
    half = len(plots) // 2
    plots.loc[half:, "time"] += gap_s
    tracker = Tracker(result.sensors, TrackerConfig())
    tracks = tracker.run(plots)
    reference = Tracker(result.sensors, TrackerConfig()).run(plots.iloc[:half])
    first_half = tracks[tracks["time"] < plots["time"].iloc[half - 1] + 100.0]
    assert len(first_half) >= len(reference) > 0
    assert tracks["time"].max() > gap_s  # the second half is tracked too
    assert tracker.stats["windows"] < 500


def test_many_lone_plots_far_apart_are_not_walked_in_full_steps():
    """Fuzz suite: 300 plots 1e9 times slower (1e8 s apart) took 25 s, each lone plot's
    tentative track making the tracker walk a full 4096-window step before the next gap was
    skipped; steps now start small after an idle gap.  Counted in windows processed (about 3 per
    plot), not timed: a fresh checkout also compiles the kernels here."""
    result = simulate(load_scenario("crossing"))
    plots = result.plots.iloc[:300].copy()
    plots["time"] *= 1e9
    tracker = Tracker(result.sensors, TrackerConfig())
    tracker.run(plots)
    assert tracker.stats["windows"] < 300 * 16  # a full first step per plot walked 300 x 4096


def test_times_beyond_the_trackers_range_are_refused():
    result = simulate(load_scenario("crossing"))
    plots = result.plots.iloc[:50].copy()
    plots.loc[plots.index[7]:, "time"] += 3.6e16
    with pytest.raises(ValueError, match=r"row 7, column time: .* s is beyond the tracker's range"):
        Tracker(result.sensors, TrackerConfig()).run(plots)

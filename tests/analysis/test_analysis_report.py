"""Report figures and the plot-position geometry of skytrack.analysis.report."""

from __future__ import annotations

import math

import matplotlib.image
import numpy as np
import pandas as pd
import pytest

from skytrack.analysis import evaluate
from skytrack.analysis.report import (
    PROJECTION_ALTITUDE,
    PROJECTION_DEFAULT_ALTITUDE,
    PROJECTION_ELEVATION,
    PROJECTION_HORIZONTAL,
    plot_metrics_over_time,
    plot_positions,
    plot_ppi,
)
from skytrack.geo import EARTH_RADIUS_M, Origin, Sensor, SensorSet, polar_to_cartesian


def sensors():
    return SensorSet(
        Origin(48.86, 2.50, 0.0),
        [
            Sensor("radar1", lat=48.86, lon=2.50, alt_m=0.0, max_range_m=100e3),
            Sensor("radar3d", type="radar-3d", x=50e3, y=-20e3, z=0.0, max_range_m=60e3),
        ],
    )


def test_positions_with_measured_elevation():
    plots = pd.DataFrame({"sensor": "radar3d", "range_m": [10e3, 30e3], "azimuth_deg": [90.0, 180.0], "elevation_deg": [0.0, 5.0]})
    pos = plot_positions(plots, sensors())
    local = np.column_stack(polar_to_cartesian(plots["range_m"].to_numpy(), np.radians([90.0, 180.0]), np.radians([0.0, 5.0])))
    np.testing.assert_allclose(pos[["x", "y", "z"]].to_numpy(), local + [50e3, -20e3, 0.0], atol=1e-6)
    assert (pos["projection"] == PROJECTION_ELEVATION).all()


def test_2d_radar_plots_use_mode_c_on_the_sphere_model():
    # a target at height h and Earth-central angle phi from the radar has slant range
    # r^2 = (a - b)^2 + 4ab sin^2(phi/2) (FORMATS.md); its ground distance along the frame is b sin(phi)
    h = 30000 * 0.3048
    phi = np.array([0.005, 0.015])
    a, b = EARTH_RADIUS_M, EARTH_RADIUS_M + h
    r = np.sqrt((a - b) ** 2 + 4 * a * b * np.sin(phi / 2) ** 2)
    plots = pd.DataFrame({"sensor": "radar1", "range_m": r, "azimuth_deg": [0.0, 45.0], "mode_c_ft": 30000.0})
    pos = plot_positions(plots, sensors())
    ground = np.hypot(pos["x"], pos["y"])
    np.testing.assert_allclose(ground, b * np.sin(phi), rtol=1e-9)
    np.testing.assert_allclose(pos["z"], b * np.cos(phi) - a, atol=1e-6)
    assert pos.loc[1, "x"] == pytest.approx(pos.loc[1, "y"])  # azimuth 45 deg
    assert (pos["projection"] == PROJECTION_ALTITUDE).all()


def test_2d_radar_plots_without_altitude():
    plots = pd.DataFrame({"sensor": "radar1", "range_m": [20e3, 40e3], "azimuth_deg": [270.0, 0.0], "mode_c_ft": [np.nan, 10000.0]})
    pos = plot_positions(plots, sensors())
    # no Mode C: the slant range is drawn horizontally, as on a PPI screen
    np.testing.assert_allclose(pos.loc[0, ["x", "y", "z"]].astype(float), [-20e3, 0.0, 0.0], atol=1e-6)
    assert pos["projection"].tolist() == [PROJECTION_HORIZONTAL, PROJECTION_ALTITUDE]
    with_default = plot_positions(plots, sensors(), default_altitude_m=5000.0)
    assert with_default["projection"].tolist() == [PROJECTION_DEFAULT_ALTITUDE, PROJECTION_ALTITUDE]
    assert with_default.loc[0, "x"] > -20e3  # the ground range is shorter than the slant range
    assert with_default.loc[0, "z"] == pytest.approx(5000.0 - 20e3**2 / (2 * EARTH_RADIUS_M), abs=40.0)


def test_plot_position_errors_name_the_row():
    plots = pd.DataFrame({"sensor": ["radar1", "nope"], "range_m": [1.0, 2.0], "azimuth_deg": [0.0, 0.0]}, index=[10, 11])
    with pytest.raises(ValueError, match=r"row 11, column 'sensor': unknown sensor 'nope'"):
        plot_positions(plots, sensors())
    plots = pd.DataFrame({"sensor": "radar1", "range_m": [1.0, np.nan], "azimuth_deg": [0.0, 0.0]})
    with pytest.raises(ValueError, match=r"row 1, column 'range_m'"):
        plot_positions(plots, sensors())
    airborne = [Sensor("awacs", type="radar-airborne")]
    with pytest.raises(ValueError, match="platform_x"):
        plot_positions(pd.DataFrame({"sensor": ["awacs"], "range_m": [1.0], "azimuth_deg": [0.0]}), airborne)


def _scene(seed=0):
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, 200.0, 4.0)
    truth, tracks, plots = [], [], []
    for i in range(12):
        p0 = rng.uniform(-80e3, 80e3, 2)
        v = rng.normal(0, 150, 2)
        xy = p0 + times[:, None] * v
        truth.append(pd.DataFrame({"time": times, "target_id": f"ac{i}", "segment": 0, "x": xy[:, 0], "y": xy[:, 1],
                                   "z": 8000.0, "vx": v[0], "vy": v[1], "vz": 0.0, "visible": True}))
        tracks.append(pd.DataFrame({"time": times[3:], "track_id": 100 + i, "x": xy[3:, 0] + 50, "y": xy[3:, 1],
                                    "z": np.nan, "vx": v[0], "vy": v[1], "vz": np.nan, "status": "confirmed"}))
        r = np.hypot(xy[:, 0], xy[:, 1])
        az = np.degrees(np.arctan2(xy[:, 0], xy[:, 1])) % 360
        plots.append(pd.DataFrame({"time": times, "sensor": "radar1", "range_m": r, "azimuth_deg": az,
                                   "mode_c_ft": 8000 / 0.3048, "truth_id": f"ac{i}"}))
    n = 400
    plots.append(pd.DataFrame({"time": rng.uniform(0, 200, n), "sensor": "radar1", "range_m": rng.uniform(0, 100e3, n),
                               "azimuth_deg": rng.uniform(0, 360, n), "mode_c_ft": np.nan, "truth_id": ""}))
    return pd.concat(plots, ignore_index=True), pd.concat(truth, ignore_index=True), pd.concat(tracks, ignore_index=True)


def _is_real_picture(path, min_bytes=20_000) -> bool:
    """A PNG of more than 500 x 500 pixels that is not a blank canvas."""
    with open(path, "rb") as f:
        signature = f.read(8)
    image = matplotlib.image.imread(path)
    return (
        path.stat().st_size > min_bytes
        and signature == b"\x89PNG\r\n\x1a\n"
        and image.shape[0] > 500
        and image.shape[1] > 500
        and float(np.std(image[..., :3])) > 0.02
    )


def test_ppi_figure_is_written(tmp_path):
    plots, truth, tracks = _scene()
    out = plot_ppi(plots, truth, tracks, sensors(), tmp_path / "ppi.png", time_window=(0.0, 150.0), dpi=80)
    assert _is_real_picture(out)


def test_ppi_figure_without_simulation_columns(tmp_path):
    plots, _, tracks = _scene()
    out = plot_ppi(plots.drop(columns=["truth_id", "mode_c_ft"]), None, tracks, sensors().sensors, tmp_path / "ppi2.png", dpi=80)
    assert _is_real_picture(out)


def test_metrics_figure_is_written(tmp_path):
    _, truth, tracks = _scene()
    ev = evaluate(tracks, truth, cutoff_m=1000.0)
    assert ev.dimension.startswith("horizontal")
    out = plot_metrics_over_time(ev, tmp_path / "metrics.png", dpi=80)
    assert _is_real_picture(out)
    assert math.isfinite(ev.summary["gospa_mean_m"])


def test_ppi_keeps_truth_and_plots_visible_and_tells_100_tracks_apart():
    """What is drawn: truth wide and light under the tracks, target plots above the tracks,
    and 100 tracks in 60 distinct (colour, dash) styles (they shared 10 colours)."""
    from matplotlib.collections import LineCollection, PathCollection

    from skytrack.analysis.report import TRACK_WIDTH, TRUTH_WIDTH, ppi_figure, track_styles

    plots, truth, tracks = _scene()
    many = pd.concat([tracks.assign(track_id=tracks["track_id"] * 1000 + k, x=tracks["x"] + 500.0 * k)
                      for k in range(100 // tracks["track_id"].nunique() + 1)], ignore_index=True)
    many = many[many["track_id"].isin(np.sort(many["track_id"].unique())[:100])]
    fig = ppi_figure(plots, truth, many, sensors(), dpi=60)
    ax = fig.axes[0]
    by_label = {c.get_label(): c for c in ax.collections if isinstance(c, LineCollection)}
    truth_lines, track_lines = by_label["truth"], by_label["tracks"]
    assert truth_lines.get_zorder() < track_lines.get_zorder()
    assert TRUTH_WIDTH >= 2.5 * TRACK_WIDTH and set(truth_lines.get_linewidths()) == {TRUTH_WIDTH}
    assert len(track_lines.get_paths()) == 100
    styles = {(tuple(np.round(c, 3)), str(d)) for c, d in track_styles(100)}
    assert len(styles) == 60
    assert len({tuple(np.round(c, 3)) for c in track_lines.get_colors()}) == 20
    dots = [c for c in ax.collections if isinstance(c, PathCollection)]
    assert max(c.get_zorder() for c in dots) > track_lines.get_zorder()  # target plots over the tracks
    assert "100 tracks" in ax.get_title()

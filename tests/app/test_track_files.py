"""Multi-file replays (issue 11 item 6): ``track_files`` and ``skytrack track-many`` give every file the
tracks of its own ``run_tracking``, in process and on a process pool; bad inputs are named."""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import shutil

import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.app.run import run_tracking
from skytrack.app.simulate import run_simulation, write_simulation
from skytrack.app.track_files import output_path, track_files
from skytrack.cli.main import app
from skytrack.io import read_tracks


@pytest.fixture(scope="module")
def two_files(tmp_path_factory):
    """Two replays of the bundled crossing scenario (seeds 5 and 6) sharing one sensors.json."""
    root = tmp_path_factory.mktemp("replays")
    files = []
    for seed in (5, 6):
        paths = write_simulation(run_simulation("crossing", seed=seed), root / f"s{seed}", "parquet")
        files.append(shutil.copy(paths["plots"], root / f"day{seed}.parquet"))
    return files, paths["sensors"]


@pytest.fixture(scope="module")
def expected(two_files, tmp_path_factory):
    """Each file's tracks from its own run_tracking."""
    files, sensors = two_files
    out = tmp_path_factory.mktemp("single")
    return [read_tracks(run_tracking(f, sensors, out / f"{i}.parquet").tracks_file) for i, f in enumerate(files)]


def test_track_files_gives_each_file_its_own_tracks_in_process_and_on_a_pool(two_files, expected, tmp_path):
    files, sensors = two_files
    calls = []
    here = track_files(files, sensors, tmp_path / "here", progress=lambda done, total: calls.append((done, total)))
    assert calls == [(0, 2), (1, 2), (2, 2)]
    with cf.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        there = track_files(files, sensors, tmp_path / "pool", executor=pool)
    for k, (a, b) in enumerate(zip(here, there)):
        assert a.tracks_file == str(output_path(files[k], tmp_path / "here"))
        assert b.tracks_file == str(tmp_path / "pool" / f"day{5 + k}.tracks.parquet")
        assert a.track_rows == b.track_rows == len(expected[k]) > 0
        assert a.stats == b.stats
        pd.testing.assert_frame_equal(read_tracks(a.tracks_file), expected[k], check_exact=True)
        pd.testing.assert_frame_equal(read_tracks(b.tracks_file), expected[k], check_exact=True)
    assert len(expected[0]) != len(expected[1]) or not expected[0].equals(expected[1])  # two different replays


def test_track_files_refuses_two_inputs_with_one_output_name_and_missing_files(two_files, tmp_path):
    files, sensors = two_files
    other = tmp_path / "elsewhere"
    other.mkdir()
    clash = shutil.copy(files[0], other / "day5.parquet")
    with pytest.raises(ValueError, match=r"would both write .*day5\.tracks\.parquet"):
        track_files([files[0], clash], sensors, tmp_path / "out")
    with pytest.raises(ValueError, match=r"plots file .*nothing\.parquet does not exist"):
        track_files([files[0], tmp_path / "nothing.parquet"], sensors, tmp_path / "out")
    with pytest.raises(ValueError, match="output format must be one of"):
        track_files(files, sensors, tmp_path / "out", output_format="xlsx")
    assert not (tmp_path / "out").exists()  # refused before anything ran


def test_track_many_cli_writes_one_tracks_file_per_input(two_files, expected, tmp_path):
    files, sensors = two_files
    result = CliRunner().invoke(app, ["track-many", *map(str, files), "--sensors", str(sensors), "--out-dir",
                                      str(tmp_path), "--format", "csv", "--workers", "1"])
    assert result.exit_code == 0, result.output
    for k, f in enumerate(files):
        got = read_tracks(output_path(f, tmp_path, "csv"))
        assert len(got) == len(expected[k])
        pd.testing.assert_series_equal(got["track_id"], expected[k]["track_id"], check_dtype=False)
        pd.testing.assert_series_equal(got["lat"], expected[k]["lat"], rtol=1e-9)
    assert "day5.parquet" in result.output and "day6.parquet" in result.output
    bad = CliRunner().invoke(app, ["track-many", str(files[0]), str(tmp_path / "missing.parquet"), "--sensors",
                                   str(sensors), "--out-dir", str(tmp_path / "x"), "--workers", "1"])
    assert bad.exit_code == 2 and "missing.parquet does not exist" in bad.output

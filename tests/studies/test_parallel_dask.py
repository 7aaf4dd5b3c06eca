"""Parallel sweeps (issue 11 item 6) on a Dask cluster: the numbers of the process pool and of the
in-process run, for singer-missed (batches of runs, E5 cells), fuzzy-crossing (case x method) and
turn-rate-adaptive (setup x configuration), through the library and through ``skytrack study ... --scheduler``.

The cluster is a ``distributed.LocalCluster`` of two single-threaded worker processes started here
(loopback only); studies are run small.  Equality is exact (``check_exact`` or byte equality).
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import multiprocessing

import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.studies import singer_missed as singer
from skytrack.studies.fuzzy import crossing
from skytrack.studies.parallel import make_executor

pytestmark = pytest.mark.slow

SINGER = singer.StudyConfig(sigmas=(100.0, 300.0), pds=(0.7, 1.0), fig1_sigma=100.0, fig2_pds=(1.0, 0.7),
                            scans=50, runs=130, seed=4)
SINGER_CLI = ["study", "singer-missed", "--sigma", "100,300", "--pd", "0.7,1", "--fig1-sigma", "100",
              "--fig2-pd", "1,0.7", "--scans", "40", "--runs", "10", "--seed", "3"]
CROSSING_CASES = [crossing.CrossingCase(policy="always", p_flip=0.1, p_code=0.1), crossing.CrossingCase(beta_deg=20.0)]


@pytest.fixture(scope="module")
def scheduler():
    """The address of a LocalCluster of two single-threaded worker processes."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


@pytest.fixture(scope="module")
def pool():
    with cf.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as executor:
        yield executor


def test_singer_study_is_identical_in_process_on_a_pool_and_on_dask(pool, scheduler):
    reference = singer.run_study(SINGER)
    pd.testing.assert_frame_equal(singer.run_study(SINGER, pool), reference, check_exact=True)
    with make_executor(scheduler=scheduler) as dask:
        pd.testing.assert_frame_equal(singer.run_study(SINGER, dask), reference, check_exact=True)
    assert reference["runs"].eq(130).all() and reference["fs11_sd"].gt(0).any()


def test_singer_monte_carlo_cells_are_identical_on_every_executor(pool, scheduler):
    from skytrack.sim.singer_truth import simulate_singer_1d

    config = singer.StudyConfig(sigmas=(100.0,), pds=(0.8,), variants=("pos", "posvel"), fig1_sigma=100.0,
                                fig2_pds=(0.8,), scans=40, seed=2)
    reference = singer.monte_carlo_consistency(config, simulate_singer_1d, 20)
    assert len(reference) == 2
    pd.testing.assert_frame_equal(singer.monte_carlo_consistency(config, simulate_singer_1d, 20, executor=pool),
                                  reference, check_exact=True)
    with make_executor(scheduler=scheduler) as dask:
        pd.testing.assert_frame_equal(singer.monte_carlo_consistency(config, simulate_singer_1d, 20, executor=dask),
                                      reference, check_exact=True)


def test_fuzzy_crossing_is_identical_in_process_on_a_pool_and_on_dask(pool, scheduler):
    methods = ("nn", "fuzzy")
    reference = crossing.run_study(CROSSING_CASES, methods, 6, 3)
    assert list(reference["method"]) == ["nn", "fuzzy"] * 2
    pd.testing.assert_frame_equal(crossing.run_study(CROSSING_CASES, methods, 6, 3, executor=pool), reference,
                                  check_exact=True)
    with make_executor(scheduler=scheduler) as dask:
        pd.testing.assert_frame_equal(crossing.run_study(CROSSING_CASES, methods, 6, 3, executor=dask), reference,
                                      check_exact=True)


# --------------------------------------------------------------------------- the CLI on a Dask cluster


def test_study_cli_with_scheduler_gives_the_numbers_of_the_process_pool(tmp_path, scheduler):
    """``skytrack study turn-rate-adaptive ... --scheduler ADDRESS``: the JSON numbers of ``--workers 2``."""
    short = ["study", "turn-rate-adaptive", "--runs", "6", "--T", "4", "--meas", "pos+rdot", "--no-imm"]
    summaries = {}
    for name, option in (("pool", ["--workers", "2"]), ("dask", ["--scheduler", scheduler])):
        result = CliRunner().invoke(app, [*short, *option, "--out", str(tmp_path / name)])
        assert result.exit_code in (0, 1), result.output  # 1: an expected behaviour failed at 6 runs
        summaries[name] = json.loads((tmp_path / name / "turn_rate_adaptive.json").read_text())
    assert summaries["dask"]["results"] == summaries["pool"]["results"]
    assert len(summaries["pool"]["results"]) == 5


def test_singer_cli_with_scheduler_writes_the_csv_of_the_process_pool(tmp_path, scheduler):
    outputs = []
    for name, option in (("pool", ["--workers", "2"]), ("dask", ["--scheduler", scheduler])):
        result = CliRunner().invoke(app, [*SINGER_CLI, *option, "--out", str(tmp_path / name)])
        assert result.exit_code == 0, result.output
        outputs.append((tmp_path / name / singer.CSV_NAME).read_bytes())
    assert outputs[0] == outputs[1]


def test_track_files_on_dask_writes_the_tracks_of_the_in_process_replay(tmp_path, scheduler):
    """Multi-file replay: two plots files tracked on the cluster give the in-process tracks, file by file."""
    import shutil

    from skytrack.app.simulate import run_simulation, write_simulation
    from skytrack.app.track_files import track_files
    from skytrack.io import read_tracks

    files = []
    for seed in (5, 6):
        paths = write_simulation(run_simulation("crossing", seed=seed), tmp_path / f"s{seed}", "parquet")
        files.append(shutil.copy(paths["plots"], tmp_path / f"day{seed}.parquet"))
    here = track_files(files, paths["sensors"], tmp_path / "here")
    with make_executor(scheduler=scheduler) as dask:
        there = track_files(files, paths["sensors"], tmp_path / "dask", executor=dask)
    for a, b in zip(here, there):
        assert a.track_rows == b.track_rows > 0 and a.stats == b.stats
        pd.testing.assert_frame_equal(read_tracks(b.tracks_file), read_tracks(a.tracks_file), check_exact=True)

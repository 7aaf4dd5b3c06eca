"""Parallel sweeps (issue 11 item 6): ``map_tasks``/``make_executor``, the fixed cut of a study into tasks,
numbers that do not depend on ``--workers``, and tasks that return what ``run_case`` used to collect.

The Dask cluster runs are in test_parallel_dask.py.  Equality is exact (byte or ``check_exact`` equality).
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import sys

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.studies import parallel
from skytrack.studies import singer_missed as singer
from skytrack.studies.fuzzy import crossing
from skytrack.studies.parallel import ExecutorError, batches, make_executor, map_tasks

SINGER = singer.StudyConfig(sigmas=(100.0, 300.0), pds=(0.7, 1.0), fig1_sigma=100.0, fig2_pds=(1.0, 0.7),
                            scans=50, runs=130, seed=4)
SINGER_CLI = ["study", "singer-missed", "--sigma", "100,300", "--pd", "0.7,1", "--fig1-sigma", "100",
              "--fig2-pd", "1,0.7", "--scans", "40", "--runs", "10", "--seed", "3"]
CROSSING_CASES = [crossing.CrossingCase(policy="always", p_flip=0.1, p_code=0.1), crossing.CrossingCase(beta_deg=20.0)]


def _pool(workers: int = 2) -> cf.ProcessPoolExecutor:
    return cf.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


@pytest.fixture(scope="module")
def pool():
    with _pool() as executor:
        yield executor


# --------------------------------------------------------------------------- map_tasks, make_executor


@pytest.mark.parametrize("use_pool", [False, True])
def test_map_tasks_returns_results_in_task_order_and_counts_progress(use_pool, pool):
    calls = []
    values = [9.0, 1.0, 16.0, 4.0, 25.0]
    got = map_tasks(math.sqrt, values, pool if use_pool else None, lambda done, total: calls.append((done, total)))
    assert got == [3.0, 1.0, 4.0, 2.0, 5.0]
    assert calls == [(k, 5) for k in range(6)]


def test_map_tasks_propagates_a_task_error(pool):
    with pytest.raises(ValueError, match="math domain error"):
        map_tasks(math.sqrt, [4.0, -1.0, 9.0], pool)


def test_batches_cut_runs_into_fixed_consecutive_ranges():
    assert batches(130, 64) == [range(0, 64), range(64, 128), range(128, 130)]
    assert batches(0) == [] and batches(5, 64) == [range(0, 5)]
    with pytest.raises(ValueError, match="size >= 1"):
        batches(5, 0)


def test_make_executor_kinds_and_errors(monkeypatch):
    with make_executor(workers=1) as executor:
        assert executor is None
    with make_executor(workers=2) as executor:
        assert isinstance(executor, cf.ProcessPoolExecutor) and executor._max_workers == 2
    monkeypatch.setenv(parallel.WORKERS_ENV, "3")
    with make_executor() as executor:
        assert executor._max_workers == 3
    monkeypatch.setenv(parallel.WORKERS_ENV, "many")
    with pytest.raises(ExecutorError, match="SKYTRACK_WORKERS must be a positive integer, got 'many'"):
        with make_executor():
            pass
    with pytest.raises(ExecutorError, match="--workers must be at least 1, got 0"):
        with make_executor(workers=0):
            pass
    monkeypatch.setitem(sys.modules, "distributed", None)  # Dask not installed
    with pytest.raises(ExecutorError, match=r"install skytrack\[dask\]"):
        with make_executor(scheduler="tcp://127.0.0.1:8786"):
            pass


def test_an_unreachable_scheduler_is_a_clear_error_within_the_timeout():
    pytest.importorskip("distributed")
    import time

    started = time.perf_counter()
    with pytest.raises(ExecutorError, match=r"cannot reach the Dask scheduler at tcp://127.0.0.1:9 within 1 s"):
        with make_executor(scheduler="tcp://127.0.0.1:9", timeout_s=1.0):
            pass
    assert time.perf_counter() - started < 10


# --------------------------------------------------------------------------- task decomposition


def test_singer_batches_are_a_faithful_cut_of_the_runs():
    """The runs cut into tasks of 64 give the numbers of one task holding every run (the cut changes nothing)."""
    tasks = singer.accuracy_tasks(SINGER)
    assert [len(t.run_seeds) for t in tasks] == [64, 64, 2] * 2
    whole = singer.AccuracyTask(SINGER, "pos", tuple(singer.run_seeds(SINGER.seed, SINGER.runs)))
    fs11, fes11 = singer.accuracy_task(whole)
    parts = [singer.accuracy_task(t) for t in tasks if t.variant == "pos"]
    np.testing.assert_allclose(np.concatenate([p[0] for p in parts], axis=-1), fs11, rtol=1e-13, atol=0)
    np.testing.assert_allclose(np.concatenate([p[1] for p in parts], axis=-1), fes11, rtol=1e-13, atol=0)


def test_singer_cli_numbers_do_not_depend_on_workers(tmp_path):
    """The accuracy table and the E5 cells (``--monte-carlo``) are byte-identical with 1 and 2 workers."""
    outputs = []
    for workers in ("1", "2"):
        out = tmp_path / f"w{workers}"
        result = CliRunner().invoke(app, [*SINGER_CLI, "--monte-carlo", "--mc-runs", "20", "--workers", workers,
                                          "--out", str(out)])
        assert result.exit_code in (0, 1), result.output  # 1: E5's ±3 % band is not for 20 runs
        assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
        outputs.append(((out / singer.CSV_NAME).read_bytes(), (out / "singer_missed_mc.csv").read_bytes()))
    assert outputs[0] == outputs[1]
    assert len(pd.read_csv(tmp_path / "w1" / singer.CSV_NAME)) == 2 * 2 * 2
    assert len(pd.read_csv(tmp_path / "w1" / "singer_missed_mc.csv")) == 2 * 2 * 2


def test_study_cli_names_an_unreachable_scheduler(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(parallel, "SCHEDULER_TIMEOUT_S", 1.0)
    result = CliRunner().invoke(app, [*SINGER_CLI, "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9 within 1 s" in result.output


def test_fuzzy_crossing_tasks_return_decisions_and_diagnostics_instead_of_filling_arguments(pool):
    task = crossing.CrossingTask(CROSSING_CASES[0], "fuzzy", 4, 3, keep_decisions=True, diagnostic_runs=1)
    here, there = crossing.crossing_task(task), map_tasks(crossing.crossing_task, [task], pool)[0]
    assert here.row == there.row
    np.testing.assert_array_equal(here.decisions.track_id, there.decisions.track_id)
    assert here.diagnostics is not None and len(here.diagnostics) > 0
    pd.testing.assert_frame_equal(here.diagnostics, there.diagnostics, check_exact=True)
    kept, pairs = {}, []
    crossing.run_case(CROSSING_CASES[0], ["fuzzy"], 4, 3, keep=kept, diagnostic_runs=1, diagnostics=pairs)
    np.testing.assert_array_equal(kept["fuzzy"].track_id, here.decisions.track_id)
    pd.testing.assert_frame_equal(pairs[0], here.diagnostics, check_exact=True)


def _mini_compare(ctx):
    ctx.compare(ctx.cases(turn_g=(4.0,)), ctx.filters(), gatings=("off", "on"))


def test_spec004_compare_gives_the_same_summary_and_progress_on_a_pool(tmp_path, pool):
    """ctx.compare's filter runs as tasks: the summary of the in-process run, progress up to every run."""
    from skytrack.studies.maneuver.study import StudyDefinition, StudyOptions, run_study

    definition = StudyDefinition("mini", "a minimal study", _mini_compare, default_runs=4,
                                 default_filters=("kf-cv", "kf-ca"))
    calls = []
    run_study(definition, StudyOptions(out=tmp_path / "here"))
    run_study(definition, StudyOptions(out=tmp_path / "pool"), lambda text, done, total: calls.append((done, total)),
              executor=pool)
    here, there = (pd.read_csv(tmp_path / name / "summary.csv") for name in ("here", "pool"))
    assert set(here["filter"]) == {"kf-cv", "kf-ca"}
    pd.testing.assert_frame_equal(here, there, check_exact=True)
    assert calls[-1] == (4, 4) and all(done <= total for done, total in calls)  # 2 filters x 2 gating modes

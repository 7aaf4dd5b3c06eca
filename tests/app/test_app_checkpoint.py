"""Checkpoint files (issue 11 item 3, :mod:`skytrack.app.checkpoint`): a tracker (and its ADS-B
labeller) saved to disk and loaded continues exactly as the original; a checkpoint of other
sensors or another configuration, of another version, or damaged, is refused with an error naming
the file; and a tracking process killed with SIGKILL is resumed from its last checkpoint by a new
process, whose tracks equal an uninterrupted run's and hold every track confirmed at that
checkpoint.

Scenario: the demo (turns, climbs, clutter, SSR replies, ADS-B; one 4-s radar, 600 s) fed in
chunks of 700 plots.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import zipfile

import numpy as np
import pandas as pd
import pytest
from checkpoint_support import CHUNK_ROWS, assert_same_tracks, chunks_of

from skytrack.app.checkpoint import (
    CheckpointError,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)
from skytrack.app.identification import TrackLabeler
from skytrack.app.other_systems import adsb_system, covered_area
from skytrack.io.sensors import sensor_set_from_dict
from skytrack.sim import load_scenario, simulate
from skytrack.tracker.bank import CONFIRMED
from skytrack.tracker.config import FilterConfig, TrackerConfig
from skytrack.tracker.tracker import Tracker


@pytest.fixture(scope="module")
def demo():
    return simulate(load_scenario("demo"))


def imm_config() -> TrackerConfig:
    config = TrackerConfig()
    config.filter = FilterConfig(kind="imm")
    return config


@pytest.mark.parametrize("config", [TrackerConfig(), imm_config()], ids=["default", "imm"])
def test_tracker_loaded_from_disk_continues_exactly(demo, tmp_path, config):
    chunks = chunks_of(demo.plots)
    original = Tracker(demo.sensors, config)
    for chunk in chunks[:6]:
        original.feed(chunk)
    original.drain()
    confirmed = set(original.bank.track_id[original.bank.status == CONFIRMED].tolist())
    path = tmp_path / "state.npz"
    save_checkpoint(path, original, extra={"frames_sent": 41})
    assert [p.name for p in tmp_path.iterdir()] == ["state.npz"]  # no temporary file left
    restored, labeler = load_checkpoint(path, demo.sensors, config)
    assert labeler is None
    assert len(confirmed) >= 10 and set(restored.bank.track_id[restored.bank.status == CONFIRMED].tolist()) == confirmed
    for chunk in chunks[6:]:
        original.feed(chunk)
        restored.feed(chunk)
    original.finish()
    restored.finish()
    expected, actual = original.drain(), restored.drain()
    assert_same_tracks(expected, actual)
    assert confirmed <= set(actual["track_id"].tolist())
    header, _ = read_checkpoint(path)
    assert header["confirmed_tracks"] == len(confirmed) and header["sensor_names"] == ["radar1"]
    assert header["extra"] == {"frames_sent": 41}


def _label_chunk(tracker: Tracker, labeler: TrackLabeler):
    """What skytrack.app.run does per chunk: drain the rows and the plots taken, label them."""
    table, _ = labeler.label(tracker.drain_arrow(), tracker.drain_assignments())
    return table


def test_adsb_labelling_is_restored_with_its_pairs(demo, tmp_path):
    """The labeller's identification pairs and sequential sums come back: labels after the restore
    are the original's (callsigns and addresses on the same rows, same identity_p)."""
    chunks = chunks_of(demo.plots)
    original = Tracker(demo.sensors, TrackerConfig())
    original.record_assignments()
    labeler = TrackLabeler(adsb_system(demo.adsb), covered_area(demo.sensors, demo.adsb))
    for chunk in chunks[:6]:
        original.feed(chunk)
        _label_chunk(original, labeler)
    assert labeler.stats.labelled_rows > 500  # pairs exist and label tracks at the checkpoint
    assert all(value.dtype != object for value in labeler.state().values())  # plain arrays, nothing pickled
    path = tmp_path / "state.npz"
    save_checkpoint(path, original, labeler)
    restored, restored_labeler = load_checkpoint(path, demo.sensors, TrackerConfig())
    assert isinstance(restored_labeler, TrackLabeler)
    assert len(restored_labeler.identifier.pairs.statistic) == len(labeler.identifier.pairs.statistic)
    expected, actual = [], []
    for chunk in chunks[6:]:
        original.feed(chunk)
        restored.feed(chunk)
        expected.append(_label_chunk(original, labeler))
        actual.append(_label_chunk(restored, restored_labeler))
    original.finish()
    restored.finish()
    expected.append(_label_chunk(original, labeler))
    actual.append(_label_chunk(restored, restored_labeler))
    expected = pd.concat([t.to_pandas() for t in expected if t is not None], ignore_index=True)
    actual = pd.concat([t.to_pandas() for t in actual if t is not None], ignore_index=True)
    assert expected["callsign"].notna().sum() > 1000
    assert_same_tracks(expected, actual)
    assert restored_labeler.stats.to_dict() == labeler.stats.to_dict()


def at(path) -> str:
    """The pattern of a file name in an error message."""
    return re.escape(str(path))


@pytest.fixture
def saved(demo, tmp_path):
    tracker = Tracker(demo.sensors, TrackerConfig())
    for chunk in chunks_of(demo.plots)[:3]:
        tracker.feed(chunk)
    path = tmp_path / "state.npz"
    save_checkpoint(path, tracker)
    return path


def test_checkpoint_of_other_sensors_is_refused(demo, saved):
    described = demo.sensors.to_dict()
    described["sensors"][0]["sigma_range_m"] = described["sensors"][0]["sigma_range_m"] * 2
    other = sensor_set_from_dict(described)
    message = rf"{at(saved)}: checkpoint was saved for other sensors \(sensors \['radar1'\]"
    with pytest.raises(CheckpointError, match=message):
        load_checkpoint(saved, other, TrackerConfig())
    # the same description read back from JSON is accepted
    same = sensor_set_from_dict(json.loads(json.dumps(demo.sensors.to_dict())))
    tracker, _ = load_checkpoint(saved, same, TrackerConfig())
    assert len(tracker.bank) > 0


def test_checkpoint_of_another_configuration_is_refused(saved, demo):
    with pytest.raises(CheckpointError, match=rf"{at(saved)}: checkpoint was saved with another tracker configuration "
                                              r"\(lifecycle.confirm_m 3 -> 2\)"):
        load_checkpoint(saved, demo.sensors, TrackerConfig(confirm_m=2))
    with pytest.raises(CheckpointError, match=r"filter.kind 'kalman-psi' -> 'imm'"):
        load_checkpoint(saved, demo.sensors, imm_config())


def test_damaged_checkpoints_are_refused_naming_the_file(saved, demo, tmp_path):
    data = saved.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match=rf"{at(truncated)}: damaged checkpoint file \({len(data) // 2} bytes; "):
        load_checkpoint(truncated, demo.sensors, TrackerConfig())
    # a flipped byte inside an array: the zip member's CRC no longer matches
    flipped = bytearray(data)
    with zipfile.ZipFile(saved) as archive:
        member = archive.getinfo("tracker.bank.state.x.npy")
    middle = member.header_offset + 30 + len(member.filename) + member.compress_size // 2
    flipped[middle] ^= 0xFF
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(bytes(flipped))
    with pytest.raises(CheckpointError, match=rf"{at(corrupt)}: damaged checkpoint file .*BadZipFile.*CRC"):
        load_checkpoint(corrupt, demo.sensors, TrackerConfig())
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a checkpoint at all")
    with pytest.raises(CheckpointError, match=rf"{at(garbage)}: damaged checkpoint file"):
        load_checkpoint(garbage, demo.sensors, TrackerConfig())
    with pytest.raises(FileNotFoundError, match="no checkpoint file"):
        load_checkpoint(tmp_path / "absent.npz", demo.sensors, TrackerConfig())
    other = tmp_path / "other.npz"
    np.savez(other, values=np.arange(3))
    with pytest.raises(CheckpointError, match=rf"{at(other)}: not a skytrack checkpoint"):
        load_checkpoint(other, demo.sensors, TrackerConfig())


def test_a_failed_write_leaves_the_previous_checkpoint(saved, demo, monkeypatch):
    """The new checkpoint goes to a temporary file first: a write that fails half-way (disk full)
    leaves the previous checkpoint whole and no temporary file behind."""
    before = saved.read_bytes()
    tracker, _ = load_checkpoint(saved, demo.sensors, TrackerConfig())
    tracker.feed(chunks_of(demo.plots)[3])

    def disk_full(handle, **arrays):
        handle.write(b"PK\x03\x04 half an archive")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", disk_full)
    with pytest.raises(OSError, match="No space left on device"):
        save_checkpoint(saved, tracker)
    assert saved.read_bytes() == before
    assert sorted(p.name for p in saved.parent.iterdir()) == ["state.npz"]
    assert len(load_checkpoint(saved, demo.sensors, TrackerConfig())[0].bank) > 0


# ---------------------------------------------------------------------------- kill -9
TRACK_AND_CHECKPOINT = textwrap.dedent("""
    # tracks the plots in chunks, checkpointing after every chunk (as the service does every few seconds)
    import sys
    import pandas as pd
    from skytrack.app.checkpoint import save_checkpoint
    from skytrack.io.sensors import read_sensors
    from skytrack.tracker.tracker import Tracker

    sensors_path, plots_path, checkpoint_path, chunk_rows = sys.argv[1:5]
    plots = pd.read_parquet(plots_path)
    tracker = Tracker(read_sensors(sensors_path))
    for k, start in enumerate(range(0, len(plots), int(chunk_rows))):
        tracker.feed(plots.iloc[start:start + int(chunk_rows)])
        tracker.drain()
        save_checkpoint(checkpoint_path, tracker)
        print("checkpoint", k + 1, flush=True)
    print("finished", flush=True)
""")

RESUME = textwrap.dedent("""
    # a restart: loads the last checkpoint, feeds the plots it had not seen, writes the tracks
    import json, sys
    import pandas as pd
    from skytrack.app.checkpoint import load_checkpoint
    from skytrack.io.sensors import read_sensors
    from skytrack.tracker.bank import CONFIRMED

    sensors_path, plots_path, checkpoint_path, chunk_rows, out_path, info_path = sys.argv[1:7]
    plots = pd.read_parquet(plots_path)
    tracker, _ = load_checkpoint(checkpoint_path, read_sensors(sensors_path), None)
    resumed_at = tracker.rows_fed
    confirmed = tracker.bank.track_id[tracker.bank.status == CONFIRMED].tolist()
    for start in range(resumed_at, len(plots), int(chunk_rows)):
        tracker.feed(plots.iloc[start:start + int(chunk_rows)])
    tracker.finish()
    tracker.drain().to_parquet(out_path)
    json.dump({"resumed_at": resumed_at, "confirmed": confirmed}, open(info_path, "w"))
""")


def test_killed_tracker_resumes_from_its_last_checkpoint(demo, tmp_path):
    sensors_path, plots_path = tmp_path / "sensors.json", tmp_path / "plots.parquet"
    sensors_path.write_text(json.dumps(demo.sensors.to_dict()))
    demo.plots.to_parquet(plots_path)
    checkpoint_path = tmp_path / "tracker.npz"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    child = subprocess.Popen([sys.executable, "-c", TRACK_AND_CHECKPOINT, str(sensors_path), str(plots_path),
                              str(checkpoint_path), str(CHUNK_ROWS)], stdout=subprocess.PIPE, text=True, env=env)
    kill_after = 7
    try:
        for line in child.stdout:
            if line.split() == ["checkpoint", str(kill_after)]:
                os.kill(child.pid, signal.SIGKILL)  # no clean-up: the process dies wherever it is
                break
        assert child.wait(timeout=60) == -signal.SIGKILL
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    # the checkpoint on disk is the 7th or a later one, whole; no temporary file is taken for it
    header, arrays = read_checkpoint(checkpoint_path)
    rows_fed = header["tracker"]["rows_fed"]
    assert rows_fed % CHUNK_ROWS == 0 and kill_after * CHUNK_ROWS <= rows_fed < len(demo.plots)
    confirmed_at_checkpoint = set(
        arrays["tracker.bank.column.track_id"][arrays["tracker.bank.column.status"] == CONFIRMED].tolist())
    assert len(confirmed_at_checkpoint) >= 10

    out_path, info_path = tmp_path / "resumed.parquet", tmp_path / "resumed.json"
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", RESUME, str(sensors_path), str(plots_path), str(checkpoint_path),
                    str(CHUNK_ROWS), str(out_path), str(info_path)], check=True, env=env, timeout=120)
    restart_s = time.perf_counter() - started
    info = json.loads(info_path.read_text())
    assert info["resumed_at"] == rows_fed
    assert set(info["confirmed"]) == confirmed_at_checkpoint  # every confirmed track resumed, same ids
    resumed = pd.read_parquet(out_path)

    # the uninterrupted run, drained at the same chunk boundary
    uninterrupted = Tracker(demo.sensors, TrackerConfig())
    chunks = chunks_of(demo.plots)
    for chunk in chunks[: rows_fed // CHUNK_ROWS]:
        uninterrupted.feed(chunk)
    uninterrupted.drain()
    for chunk in chunks[rows_fed // CHUNK_ROWS:]:
        uninterrupted.feed(chunk)
    uninterrupted.finish()
    expected = uninterrupted.drain()
    assert_same_tracks(expected.reset_index(drop=True), resumed.reset_index(drop=True))
    # confirmed tracks still reported (fewer than report_max_misses misses) appear at the first output instant
    columns = arrays["tracker.bank.column.n_misses"]
    reported = set(arrays["tracker.bank.column.track_id"][(arrays["tracker.bank.column.status"] == CONFIRMED)
                                                         & (columns < 4)].tolist())
    first_instant = resumed["time"].min()
    assert reported <= set(resumed.loc[resumed["time"] == first_instant, "track_id"].tolist())
    assert restart_s < 60

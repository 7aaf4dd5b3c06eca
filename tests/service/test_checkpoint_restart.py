"""skytrack serve's checkpoints (issue 11 item 3 acceptance): kill -9 of a running service and a restart resume
every track confirmed at the last checkpoint; a damaged checkpoint is reported and set aside."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from skytrack.io.asterix.recording import encode_recording
from skytrack.service.pipeline import sensor_sac_sic, time_of_day_at_epoch
from skytrack.service.replay import Replayer, scan_blocks
from skytrack.service.server import CHECKPOINT_NAME, resume_or_start


def _free_port(kind) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _health(port: int) -> dict:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=5) as response:
        return json.loads(response.read())


def _start(sensors_path, udp_port, http_port, checkpoint_dir, log_path):
    log = open(log_path, "w")
    process = subprocess.Popen(
        [sys.executable, "-m", "skytrack", "serve", "--sensors", str(sensors_path), "--udp", f"127.0.0.1:{udp_port}",
         "--http", f"127.0.0.1:{http_port}", "--checkpoint-dir", str(checkpoint_dir), "--checkpoint-every-s", "1",
         "--reorder-window-s", "1"], stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "COLUMNS": "200"})
    deadline = time.time() + 60
    while time.time() < deadline:
        try:
            return process, _health(http_port)
        except OSError:
            assert process.poll() is None, log_path.read_text()
            time.sleep(0.2)
    raise AssertionError(f"serve did not start: {log_path.read_text()}")


def _send(sensors, plots, udp_port, speed=30.0):
    data = encode_recording(plots, sensor_sac_sic(sensors), max_records_per_block=60,
                            time_of_day_at_epoch_s=time_of_day_at_epoch(sensors.epoch_utc))
    return Replayer(scan_blocks(np.frombuffer(data, np.uint8)), ("127.0.0.1", udp_port), speed=speed).run()


@pytest.mark.slow
def test_kill_9_and_restart_resume_every_confirmed_track(small_scene, tmp_path):
    from skytrack.app.checkpoint import load_checkpoint
    from skytrack.io import write_sensors
    from skytrack.tracker.bank import CONFIRMED

    sensors, plots = small_scene
    sensors_path = tmp_path / "sensors.json"
    write_sensors(sensors, sensors_path)
    udp_port, http_port = _free_port(socket.SOCK_DGRAM), _free_port(socket.SOCK_STREAM)
    checkpoint_dir = tmp_path / "checkpoints"
    first, _ = _start(sensors_path, udp_port, http_port, checkpoint_dir, tmp_path / "serve1.log")
    try:
        _send(sensors, plots[plots["time"] < 60.0], udp_port)
        # the feed is idle: the last plots leave the reorder buffer, then a checkpoint holds them all
        deadline = time.time() + 20
        while time.time() < deadline:
            health = _health(http_port)
            fresh = (health["checkpoint_age_s"] or 99.0) < 0.5
            if health["plots_tracked"] == int((plots["time"] < 60.0).sum()) and fresh:
                break
            time.sleep(0.1)
        time.sleep(1.5)  # one more checkpoint after everything was tracked
        assert health["confirmed_tracks"] >= 10
    finally:
        first.send_signal(signal.SIGKILL)
        first.wait(timeout=10)
    assert first.returncode == -signal.SIGKILL
    tracker, _ = load_checkpoint(checkpoint_dir / CHECKPOINT_NAME, sensors)
    confirmed_at_checkpoint = set(tracker.bank.track_id[tracker.bank.status == CONFIRMED].tolist())
    assert len(confirmed_at_checkpoint) >= 10

    second, health = _start(sensors_path, udp_port, http_port, checkpoint_dir, tmp_path / "serve2.log")
    try:
        assert "resumed from checkpoint" in (tmp_path / "serve2.log").read_text()
        assert health["resumed_from"].endswith(CHECKPOINT_NAME)
        assert confirmed_at_checkpoint <= set(health["track_ids"])
        # the tracks go on with the plots that follow: most of them are still confirmed 20 s later
        _send(sensors, plots[(plots["time"] >= 60.0) & (plots["time"] < 80.0)], udp_port)
        time.sleep(2.5)
        health = _health(http_port)
        assert health["plots_late"] == 0 and health["recent_errors"] == []
        kept = confirmed_at_checkpoint & set(health["track_ids"])
        assert len(kept) >= 0.8 * len(confirmed_at_checkpoint)
    finally:
        second.send_signal(signal.SIGINT)
        second.wait(timeout=15)


def test_damaged_checkpoint_is_reported_and_set_aside(small_scene, tmp_path):
    sensors, _ = small_scene
    (tmp_path / CHECKPOINT_NAME).write_bytes(b"PK\x03\x04 not really a zip")
    said = []
    tracker, labeler, resumed = resume_or_start(sensors, None, tmp_path, None, said.append)
    assert resumed is None and len(tracker.bank) == 0 and labeler is None
    assert said[0].startswith("CHECKPOINT NOT USED:") and "damaged checkpoint" in said[0]
    assert (tmp_path / (CHECKPOINT_NAME + ".damaged")).exists() and not (tmp_path / CHECKPOINT_NAME).exists()
    said.clear()
    resume_or_start(sensors, None, tmp_path, None, said.append)
    assert said[0].startswith(f"no checkpoint in {tmp_path}")

"""The serve and replay commands (skytrack.cli.serve): option errors, replay of a plots table to a socket, and
``skytrack serve --demo`` end to end (subprocess: tracks appear, labelled with the demo's callsigns)."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.io.asterix import decode_asterix

runner = CliRunner()


def _free_port(kind) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_option_errors_are_named():
    result = runner.invoke(app, ["serve"])
    assert result.exit_code == 2 and "--sensors is required (or --demo)" in result.output
    result = runner.invoke(app, ["serve", "--demo", "--sensors", "x.json"])
    assert result.exit_code == 2 and "leave out --sensors" in result.output
    result = runner.invoke(app, ["serve", "--sensors", "x.json", "--udp", "localhost:http"])
    assert result.exit_code == 2 and "expected HOST:PORT" in result.output
    result = runner.invoke(app, ["replay", "x.parquet", "--to", "tcp://1.2.3.4:5"])
    assert result.exit_code == 2 and "udp://HOST:PORT" in result.output


def test_replay_a_plots_table(small_scene, tmp_path):
    from skytrack.io import write_sensors

    sensors, plots = small_scene
    write_sensors(sensors, tmp_path / "sensors.json")
    head = plots[plots["time"] < 20.0]
    head.to_parquet(tmp_path / "plots.parquet")
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(0.5)
    port = receiver.getsockname()[1]
    result = runner.invoke(app, ["replay", str(tmp_path / "plots.parquet"), "--sensors", str(tmp_path / "sensors.json"),
                                 "--to", f"udp://127.0.0.1:{port}", "--speed", "100"])
    assert result.exit_code == 0, result.output
    assert f"sent {len(head)} records ({len(head)} plots) in" in result.output
    received = []
    while True:
        try:
            received.append(receiver.recv(65536))
        except socket.timeout:
            break
    receiver.close()
    assert len(decode_asterix(b"".join(received)).plots["time"]) == len(head)
    result = runner.invoke(app, ["replay", str(tmp_path / "plots.parquet"), "--to", f"udp://127.0.0.1:{port}"])
    assert result.exit_code == 2 and "give --sensors" in result.output


@pytest.mark.slow
def test_serve_demo_tracks_and_labels_the_demo_traffic(tmp_path):
    from websockets.sync.client import connect

    udp_port, http_port = _free_port(socket.SOCK_DGRAM), _free_port(socket.SOCK_STREAM)
    log_path = tmp_path / "serve.log"
    with open(log_path, "w") as log:
        process = subprocess.Popen([sys.executable, "-m", "skytrack", "serve", "--demo", "--speed", "30", "--udp",
                                    f"127.0.0.1:{udp_port}", "--http", f"127.0.0.1:{http_port}"],
                                   stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "COLUMNS": "200"})
    try:
        deadline = time.time() + 90
        while time.time() < deadline and f"http://127.0.0.1:{http_port}/" not in log_path.read_text():
            assert process.poll() is None, log_path.read_text()
            time.sleep(0.2)
        callsigns = set()
        with connect(f"ws://127.0.0.1:{http_port}/ws", max_size=None) as ws:
            assert json.loads(ws.recv())["sensors"][0]["name"] == "radar1"
            end = time.time() + 25
            while time.time() < end and len(callsigns) < 10:
                message = ws.recv(timeout=10)
                if isinstance(message, str) and json.loads(message)["type"] == "labels":
                    callsigns |= {v["callsign"] for v in json.loads(message)["labels"].values() if v["callsign"]}
        with urllib.request.urlopen(f"http://127.0.0.1:{http_port}/health", timeout=5) as response:
            health = json.loads(response.read())
        # the demo's aircraft are tracked and the ADS-B test names them (DEMO1.. are the scripted ones)
        assert health["confirmed_tracks"] >= 10 and health["plots_late"] == 0
        assert len(callsigns) >= 10 and any(c.startswith("DEMO") for c in callsigns)
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=20)
    assert "demo: 12339 plots" in log_path.read_text()

"""Issue 8: the airborne-radar crossing scenario from ``skytrack simulate`` through ``skytrack track``
with spec 003's fuzzy rule: tracks carry the identity of the aircraft they follow."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pandas as pd
import yaml
from typer.testing import CliRunner

from skytrack.cli.main import app


def test_simulate_and_track_the_airborne_crossings(tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["simulate", "airborne_crossing", "--out", str(tmp_path / "sim")])
    assert result.exit_code == 0, result.output
    sim = tmp_path / "sim"
    assert '"radar-airborne"' in (sim / "sensors.json").read_text()
    out = tmp_path / "tracks.parquet"
    result = runner.invoke(app, ["track", str(sim / "plots.parquet"), "--sensors", str(sim / "sensors.json"),
                                 "--out", str(out), "--association-rule", "fuzzy"])
    assert result.exit_code == 0, result.output
    assert "3-D" in result.output and "identity events" in result.output
    tracks = pd.read_parquet(out)
    truth = pd.read_parquet(sim / "truth.parquet")
    scenario = yaml.safe_load(resources.files("skytrack.scenarios").joinpath("airborne_crossing.yaml").read_text())
    status = {t["id"]: t["iff"] for t in scenario["targets"]}
    code = {t["id"]: t["mode3a"] for t in scenario["targets"]}
    last = tracks.sort_values("time").groupby("track_id").tail(1)
    assert len(last) == len(status)  # one confirmed track per aircraft
    for row in last.itertuples():
        at = truth[np.isclose(truth["time"], np.round(row.time))]
        nearest = at.iloc[int(np.argmin(np.hypot(at["x"] - row.x, at["y"] - row.y)))]["target_id"]
        assert row.iff == status[nearest] and row.mode3a == code[nearest]
        assert row.identity_source == "iff" and 0.9 < row.identity_p <= 1.0
    events = pd.read_parquet(tmp_path / "tracks.identity.parquet")
    first = events.sort_values("time").groupby(["track_id", "field"]).head(1)
    assert first["old"].isna().all()  # every identity starts from unknown
    assert set(events["field"]) >= {"iff", "mode3a"}
    # the last event of each (track, field) is the value the track shows at the end
    final = events.sort_values("time").groupby(["track_id", "field"]).tail(1)
    shown = last.set_index("track_id")
    for row in final.itertuples():
        assert shown.loc[row.track_id, row.field] == row.new

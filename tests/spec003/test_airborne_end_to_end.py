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


def test_range_rate_positive_closing_is_negated_on_reading(tmp_path):
    """Spec 003 R2: a file whose range rates are positive for closing targets, read with
    --range-rate-positive-closing, tracks exactly as the dD/dt file does."""
    runner = CliRunner()
    assert runner.invoke(app, ["simulate", "airborne_crossing", "--out", str(tmp_path / "sim")]).exit_code == 0
    sim = tmp_path / "sim"
    plots = pd.read_parquet(sim / "plots.parquet")
    assert (plots["range_rate_mps"] < 0).mean() > 0.5  # most targets close on the carrier: dD/dt < 0
    flipped = plots.assign(range_rate_mps=-plots["range_rate_mps"])
    flipped.to_parquet(tmp_path / "closing.parquet")
    common = ["--sensors", str(sim / "sensors.json")]
    assert runner.invoke(app, ["track", str(sim / "plots.parquet"), *common, "--out", str(tmp_path / "a.parquet")]).exit_code == 0
    result = runner.invoke(app, ["track", str(tmp_path / "closing.parquet"), *common, "--out", str(tmp_path / "b.parquet"),
                                 "--range-rate-positive-closing"])
    assert result.exit_code == 0, result.output
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "a.parquet"), pd.read_parquet(tmp_path / "b.parquet"))
    wrong = runner.invoke(app, ["track", str(tmp_path / "closing.parquet"), *common, "--out", str(tmp_path / "c.parquet")])
    assert wrong.exit_code == 0
    assert not pd.read_parquet(tmp_path / "c.parquet")[["x", "y"]].equals(pd.read_parquet(tmp_path / "a.parquet")[["x", "y"]])

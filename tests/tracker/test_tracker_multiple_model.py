"""The multiple-model filters inside the tracker (issue 7, item 2): configuration, the
``model_probs`` column, the IMM's manoeuvre gate, the static bank, and the command line."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from skytrack.cli.main import app
from skytrack.sim import load_scenario, simulate
from skytrack.tracker.config import TRACKER_MODEL_SET, FilterConfig, TrackerConfig
from skytrack.tracker.tracker import Tracker


@pytest.fixture(scope="module")
def crossing():
    return simulate(load_scenario("crossing"))


def imm_config(**options) -> TrackerConfig:
    config = TrackerConfig()
    config.filter = FilterConfig(kind="imm", options=options)
    return config


def test_model_probs_column_names_the_models_and_sums_to_one(crossing):
    tracker = Tracker(crossing.sensors, imm_config())
    tracks = tracker.run(crossing.plots)
    assert len(tracks) > 100
    names = tracker.filter.names
    assert len(names) == 4 and names[0] == "CV"  # the tracker's default set, cv-ct-noisy
    parsed = [json.loads(text) for text in tracks["model_probs"]]
    assert all(list(p) == list(names) for p in parsed)
    sums = np.array([sum(p.values()) for p in parsed])
    # four values printed with 4 significant digits: each off by at most 5e-5
    np.testing.assert_allclose(sums, 1.0, atol=4 * 5e-5)
    # a straight crossing: the quiet CV mode dominates most reported rows
    assert np.median([p["CV"] for p in parsed]) > 0.5


def test_single_model_filters_leave_model_probs_null(crossing):
    tracks = Tracker(crossing.sensors, TrackerConfig()).run(crossing.plots)
    assert tracks["model_probs"].isna().all()


def test_imm_manoeuvre_gate_is_used_and_can_be_switched_off():
    """On the demo scenario (turns, climbs, clutter) the IMM's manoeuvre gate finds plots that the
    mixture's gate missed; without it the gate stage does not run."""
    demo = simulate(load_scenario("demo"))
    with_gate = Tracker(demo.sensors, imm_config())
    with_gate.run(demo.plots)
    without = Tracker(demo.sensors, imm_config(manoeuvre_gate=False))
    without.run(demo.plots)
    assert with_gate.scan.manoeuvre_gate and with_gate.scan.stats["manoeuvre_gate_hits"] > 0
    assert not without.scan.manoeuvre_gate and without.scan.stats["manoeuvre_gate_hits"] == 0


def test_static_bank_runs_inside_the_tracker(crossing):
    config = TrackerConfig()
    config.filter = FilterConfig(kind="static-bank")
    tracker = Tracker(crossing.sensors, config)
    tracks = tracker.run(crossing.plots)
    baseline = Tracker(crossing.sensors, TrackerConfig()).run(crossing.plots)
    assert tracks["track_id"].nunique() >= 0.8 * baseline["track_id"].nunique()
    parsed = [json.loads(text) for text in tracks["model_probs"]]
    assert len(parsed[0]) == 4
    np.testing.assert_allclose([sum(p.values()) for p in parsed], 1.0, atol=4 * 5e-5)


def test_model_set_configuration_round_trips_and_is_checked(tmp_path):
    path = tmp_path / "tracker.yaml"
    path.write_text("filter:\n  kind: imm\n  model_set: cv-ct\n")
    config = TrackerConfig.from_file(path)
    assert config.model_set == "cv-ct" and config.filter.kind == "imm"
    filt = config.filter.build(config.motion_model(3), config.motion)
    assert len(filt.modes) == 3 and filt.names[0] == "CV"
    assert TrackerConfig(filter_kind="imm").filter.model_set is None  # the tracker's default set
    with pytest.raises(ValueError, match="applies to the multiple-model filters"):
        TrackerConfig(model_set="cv-ct").filter.build(config.motion_model(3), config.motion)
    with pytest.raises(ValueError, match="needs 3 states per axis"):
        TrackerConfig(filter_kind="imm", model_set="cv-ca").filter.build(config.motion_model(3), config.motion)
    singer = TrackerConfig(filter_kind="imm", model_set="cv-ca", model="singer")
    assert singer.filter.build(singer.motion_model(3), singer.motion).state_dim == 9
    assert TRACKER_MODEL_SET == "cv-ct-noisy"


def test_cli_track_with_imm_and_model_set(tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["simulate", "crossing", "-o", str(tmp_path)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    out = tmp_path / "imm.parquet"
    args = ["track", str(tmp_path / "plots.parquet"), "--sensors", str(tmp_path / "sensors.json"), "-o", str(out)]
    result = runner.invoke(app, args + ["--filter", "imm", "--model-set", "cv-ct"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    tracks = pd.read_parquet(out)
    # the tracker's turn rate (3 deg/s for civil traffic), not spec 004's fighter default
    assert list(json.loads(tracks["model_probs"].iloc[0])) == ["CV", "CT +3 deg/s", "CT -3 deg/s"]
    result = runner.invoke(app, args + ["--filter", "imm", "--model-set", "cv-ca"], catch_exceptions=False)
    assert result.exit_code != 0 and "--model singer" in result.output
    result = runner.invoke(app, args + ["--model-set", "cv-ct"], catch_exceptions=False)
    assert result.exit_code != 0 and "multiple-model" in result.output


def test_compiled_imm_stage_equals_the_composed_reference(crossing):
    """The IMM's compiled association stage (tracker/imm_stage_kernel.py) against the composed
    parts with the numpy IMM: the same rows, states to 1e-6 m and m/s, the same model
    probabilities to 1e-6; the manoeuvre gate and two-point starts run on both paths."""
    outputs = {}
    for compiled in (True, False):
        config = imm_config(compiled=compiled)
        config.initiation.method = "two-point"
        tracker = Tracker(crossing.sensors, config)
        outputs[compiled] = (tracker.run(crossing.plots), tracker)
    (fast, fast_tracker), (reference, reference_tracker) = outputs[True], outputs[False]
    assert fast_tracker.scan.fused_imm is not None and reference_tracker.scan.fused_imm is None
    assert len(fast) == len(reference) > 100
    np.testing.assert_array_equal(fast["track_id"], reference["track_id"])
    for column in ("x", "y", "z", "vx", "vy", "vz"):
        np.testing.assert_allclose(fast[column], reference[column], rtol=0, atol=1e-6, err_msg=column)
    probs = np.array([[v for v in json.loads(t).values()] for t in fast["model_probs"]])
    probs_ref = np.array([[v for v in json.loads(t).values()] for t in reference["model_probs"]])
    np.testing.assert_allclose(probs, probs_ref, rtol=0, atol=1.5e-4)  # 4-decimal text
    assert fast_tracker.scan.stats["manoeuvre_gate_hits"] == reference_tracker.scan.stats["manoeuvre_gate_hits"]
    np.testing.assert_allclose(fast_tracker.bank.state.mu, reference_tracker.bank.state.mu, rtol=0, atol=1e-6)


def test_model_probs_text_is_json_with_four_decimals(monkeypatch):
    """Fixed-width text: rounding to 4 decimals, 1 and 0 written out, names JSON-escaped, and the
    same text when the rows are split into several pyarrow chunks."""
    from skytrack.tracker import output

    names = ("CV", 'say "turn"', "Kurve δ")
    probabilities = np.array([[1.0, 0.0, 0.0], [0.12344, 0.87656, 0.0], [0.99996, 0.00004, 0.0]])
    text = output.model_probs_text(probabilities, names).to_pylist()
    assert text[0] == '{"CV": 1.0000, "say \\"turn\\"": 0.0000, "Kurve \\u03b4": 0.0000}'
    assert json.loads(text[1]) == {"CV": 0.1234, 'say "turn"': 0.8766, "Kurve δ": 0.0}
    assert json.loads(text[2])["CV"] == 1.0
    monkeypatch.setattr(output, "MAX_STRING_CHUNK_BYTES", 2 * len(text[0]))
    chunked = output.model_probs_text(probabilities, names)
    assert chunked.num_chunks == 2 and chunked.to_pylist() == text
    assert len(output.model_probs_text(np.zeros((0, 3)), names)) == 0

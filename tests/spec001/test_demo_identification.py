"""Issue 9 item 7: the demo shows the identified air picture (spec 001 R13 through the tracker).

* the demo scenario's ADS-B: about 80 % of the aircraft transmit, the close pair (1 km apart
  for 3 minutes, both equipped, no Mode S address), the faulty transponder (2 km offset), and
  the radar plots do not depend on ADS-B (separate random streams);
* the PPI figure (:func:`skytrack.analysis.report.ppi_figure`): what is drawn — the text
  artists carry the callsigns (else the addresses) of the tracks identified at their last row
  and no identity a track has lost, each at its track's last position at the end of a leader,
  the labels of a close pair do not overlap on the page, and 120 tracks keep their distinct
  styles and one legend entry per kind.

The demo run itself (identification.json, the checks, the printed summary) is tested with
the other demo tests in tests/cli/test_cli.py.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import LineCollection
from matplotlib.text import Annotation

from skytrack.analysis.report import LEADER_WIDTH, place_labels, ppi_figure, track_identities
from skytrack.geo import Origin, Sensor, SensorSet
from skytrack.sim import load_scenario, simulate

KM = 1000.0


# ------------------------------------------------------------------ the demo scenario


@pytest.fixture(scope="module")
def demo():
    scenario = load_scenario("demo")
    return scenario, simulate(scenario)


def test_demo_scenario_has_adsb_for_80_percent_with_the_pair_and_the_offset(demo):
    scenario, result = demo
    aircraft = result.adsb_aircraft.set_index("target_id")
    assert len(aircraft) == len(scenario.all_targets()) == 78
    # 3 marked equipped + round(0.8 x 74) of the others with a transponder (DEMO3 has none)
    assert int(aircraft["equipped"].sum()) == 3 + round(0.8 * 74) == 62
    assert 0.75 <= aircraft["equipped"].mean() <= 0.85
    assert not aircraft.at["DEMO3", "equipped"]
    assert aircraft.loc[["DEMO4", "DEMO5", "DEMO6"], "equipped"].all()
    faulty = aircraft[aircraft["fault"].astype(str).str.strip() != ""]
    assert list(faulty.index) == ["DEMO4"] and faulty.at["DEMO4", "fault"] == "offset"
    assert (faulty.at["DEMO4", "offset_x_m"], faulty.at["DEMO4", "offset_y_m"]) == (2000.0, 0.0)
    reports = result.adsb
    assert set(reports["truth_id"]) == set(aircraft.index[aircraft["equipped"]])
    assert (reports["sigma_m"] == 12.0).all()
    # 1 s reports with 3 % lost: a 600-s aircraft sends about 582 (binomial sd 4; 5 sd band)
    per_aircraft = reports.groupby("truth_id").size()
    assert abs(per_aircraft["DEMO5"] - 0.97 * 600) < 5 * np.sqrt(600 * 0.03 * 0.97)
    # the offset aircraft's reports sit 2 km east of its truth (noise sigma 12 m)
    truth = result.truth.set_index(["target_id", "time"])
    offset = reports[reports["truth_id"] == "DEMO4"]
    at = np.round(offset["time"].to_numpy())
    keep = pd.MultiIndex.from_arrays([["DEMO4"] * at.size, at]).isin(truth.index)
    true_xy = truth.loc[[("DEMO4", t) for t in at[keep]], ["x", "y"]].to_numpy()
    speed = 110.0  # m/s: the report is up to 0.55 s off the truth sample it is compared with
    error = offset[["x", "y"]].to_numpy()[keep] - true_xy
    assert abs(np.mean(error[:, 0]) - 2000.0) < speed * 0.6 and abs(np.mean(error[:, 1])) < speed * 0.6


def test_demo_pair_flies_1_km_apart_for_3_minutes_without_mode_s(demo):
    scenario, result = demo
    truth = result.truth.set_index(["target_id", "time"])
    for t in np.arange(0.0, 181.0, 10.0):
        gap = truth.loc[("DEMO6", t), ["x", "y"]].to_numpy(float) - truth.loc[("DEMO5", t), ["x", "y"]].to_numpy(float)
        assert np.hypot(*gap) == pytest.approx(1000.0, abs=1e-6)
    assert np.hypot(*(truth.loc[("DEMO6", 300.0), ["x", "y"]].to_numpy(float)
                      - truth.loc[("DEMO5", 300.0), ["x", "y"]].to_numpy(float))) > 10_000.0
    targets = {t.id: t for t in scenario.all_targets()}
    assert targets["DEMO5"].icao24 is None and targets["DEMO6"].icao24 is None
    pair_plots = result.plots[result.plots["truth_id"].isin(["DEMO5", "DEMO6"])]
    assert pair_plots["mode_s"].isna().all() and len(pair_plots) > 200
    callsigns = result.adsb_aircraft.set_index("target_id")["sent_callsign"]
    assert (callsigns["DEMO5"], callsigns["DEMO6"]) == ("AFR451", "AFR453")


def test_demo_radar_plots_do_not_depend_on_adsb(demo):
    scenario, result = demo
    without = simulate(dataclasses.replace(scenario, adsb=None))
    assert without.adsb is None
    pd.testing.assert_frame_equal(result.plots, without.plots)
    pd.testing.assert_frame_equal(result.truth, without.truth)


# ------------------------------------------------------------------ the PPI's identities


def _sensors():
    return SensorSet(Origin(48.86, 2.50, 0.0), [Sensor("radar1", lat=48.86, lon=2.50, alt_m=0.0, max_range_m=150e3)])


def _tracks(count: int, seed: int = 1) -> pd.DataFrame:
    """``count`` straight tracks over 100 s, spread over the coverage, no identities."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, 101.0, 4.0)
    rows = []
    for k in range(count):
        start = rng.uniform(-120e3, 120e3, 2)
        velocity = rng.normal(0.0, 150.0, 2)
        xy = start + times[:, None] * velocity
        rows.append(pd.DataFrame({"time": times, "track_id": 10 + k, "x": xy[:, 0], "y": xy[:, 1],
                                  "status": "confirmed", "icao24": None, "callsign": None}))
    return pd.concat(rows, ignore_index=True).astype({"icao24": object, "callsign": object})


def _label(tracks: pd.DataFrame, track_id: int, icao24, callsign, rows: slice = slice(None)) -> None:
    index = tracks.index[tracks["track_id"] == track_id][rows]
    tracks.loc[index, "icao24"] = icao24
    tracks.loc[index, "callsign"] = callsign


def _annotations(fig) -> dict[str, Annotation]:
    return {a.get_text(): a for a in fig.axes[0].texts if isinstance(a, Annotation)}


def test_ppi_labels_identified_tracks_with_callsign_or_address_at_their_last_position():
    tracks = _tracks(8)
    _label(tracks, 10, "3c6a01", "AFR451", slice(3, None))  # identified after 3 scans
    _label(tracks, 11, "4ca7b5", None, slice(5, None))  # address, no callsign
    _label(tracks, 12, "39ab01", "DLH9", slice(0, 10))  # lost its label: not identified any more
    _label(tracks, 13, "39ab02", "BAW12")
    fig = ppi_figure(None, None, tracks, _sensors(), n_track_labels=2, dpi=60)
    drawn = _annotations(fig)
    assert {"AFR451", "4ca7b5", "BAW12"} <= set(drawn)
    assert "DLH9" not in drawn and "39ab01" not in drawn and "3c6a01" not in drawn and "39ab02" not in drawn
    # the two longest unidentified tracks keep their ids (all are equally long: the first two
    # in track order), the identified ones do not show theirs
    assert {"12", "14"} <= set(drawn) and not {"10", "11", "13", "15"} & set(drawn)
    last = tracks.sort_values("time").groupby("track_id")[["x", "y"]].last() / KM
    for text, track_id in (("AFR451", 10), ("4ca7b5", 11), ("BAW12", 13)):
        annotation = drawn[text]
        np.testing.assert_allclose(annotation.xy, last.loc[track_id].to_numpy(), rtol=0, atol=1e-9)
        dx, dy = annotation.xyann
        assert np.hypot(dx, dy) >= 8.0  # the label sits at the end of its leader, off the track's end
        assert annotation.arrow_patch is not None and annotation.arrow_patch.get_linewidth() == LEADER_WIDTH
        assert annotation.get_fontsize() <= 7.0
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any("3 identified tracks" in t for t in legend)


def test_track_identities_takes_the_last_row():
    tracks = _tracks(3)
    _label(tracks, 10, "3c6a01", "AFR451")
    _label(tracks, 11, "4ca7b5", "  ")  # blank callsign: the address
    identities = track_identities(tracks)
    assert identities["label"].to_dict() == {10: "AFR451", 11: "4ca7b5", 12: None}
    assert track_identities(tracks.drop(columns=["icao24", "callsign"]))["label"].isna().all()


def test_close_pair_labels_do_not_overlap_on_the_page():
    """Two identified tracks 1 km apart (on a 300-km wide picture: 3 points) get labels that
    do not cover each other once drawn."""
    tracks = _tracks(2)
    pair = tracks[tracks["track_id"] == 10]
    tracks = pd.concat([pair, pair.assign(track_id=11, y=pair["y"] + 1000.0)], ignore_index=True)
    _label(tracks, 10, "3c6a01", "AFR451")
    _label(tracks, 11, "3c6a02", "AFR453")
    fig = ppi_figure(None, None, tracks, _sensors(), dpi=100)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    drawn = _annotations(fig)
    # the label boxes (an annotation's own extent also spans its leader, down to the anchor)
    first, second = (drawn[t].get_bbox_patch().get_window_extent(renderer) for t in ("AFR451", "AFR453"))
    assert first.width > 10 and second.width > 10
    assert not first.overlaps(second)


def test_place_labels_avoids_boxes_and_anchors():
    anchors = np.array([[100.0, 100.0], [100.0, 103.0], [104.0, 100.0], [300.0, 300.0]])
    sizes = np.array([[30.0, 10.0]] * 4)
    offsets = place_labels(anchors, sizes)
    assert offsets.shape == (4, 2) and (np.hypot(*offsets.T) >= 9.0).all()
    # rebuild the boxes as place_labels lays them out and check that none overlaps another
    # box or an anchor
    boxes = []
    for (x, y), (dx, dy), (w, h) in zip(anchors, offsets, sizes):
        x0 = x + dx - (0.0 if dx > 0 else w if dx < 0 else w / 2)
        y0 = y + dy - (0.0 if dy > 0 else h if dy < 0 else h / 2)
        boxes.append((x0, y0, x0 + w, y0 + h))
    boxes = np.array(boxes)
    for i in range(4):
        for j in range(4):
            if i != j:
                a, b = boxes[i], boxes[j]
                assert min(a[2], b[2]) <= max(a[0], b[0]) or min(a[3], b[3]) <= max(a[1], b[1])
                px, py = anchors[j]
                assert not (a[0] < px < a[2] and a[1] < py < a[3])


def test_ppi_with_120_tracks_keeps_styles_legend_and_every_identity():
    tracks = _tracks(120, seed=3)
    identified = list(range(10, 130, 2))  # 60 of them
    for k in identified:
        _label(tracks, k, f"{k:06x}", f"SKY{k}")
    fig = ppi_figure(None, None, tracks, _sensors(), dpi=60)
    ax = fig.axes[0]
    track_lines = {c.get_label(): c for c in ax.collections if isinstance(c, LineCollection)}["tracks"]
    assert len(track_lines.get_paths()) == 120
    styles = {(tuple(np.round(c, 3)), str(d)) for c, d in zip(track_lines.get_colors(), track_lines.get_linestyles())}
    assert len(styles) == 60
    drawn = _annotations(fig)
    assert {f"SKY{k}" for k in identified} <= set(drawn)
    assert not {f"SKY{k}" for k in range(11, 130, 2)} & set(drawn)
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(legend) == 3  # tracks, identities, radar: one entry per kind, not per track
    assert any("60 identified tracks" in t for t in legend) and any("120, 60 styles" in t for t in legend)

"""Issue 9 items 3/4/7: the identification report against truth
(skytrack.analysis.identification) and its rich printout (skytrack.cli.identification_view).

Synthetic tracks, truth and ADS-B built here, with every count worked out by hand from the
construction: aircraft far apart (tens of km) flying straight, tracks 50 m off their truth at
every 2 s output instant, so the association (gate 2 km) is never in doubt.  Every status,
total and table row is asserted exactly (the fraction of correct rows to 1e-12).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from rich.console import Console

from skytrack.analysis.identification import STATUSES, identification_report
from skytrack.cli.identification_view import identification_table

TIMES = np.arange(0.0, 300.0, 2.0)  # output instants 0, 2, ..., 298 s: 150 of them
#: aircraft: id -> (address sent, x0, y0); all fly east at 200 m/s, 30 km apart
AIRCRAFT = {"A": "aaa001", "B": "bbb002", "C": "ccc003", "D": "ddd004", "E": "eee005", "F": "fff006",
            "O": "0ff007", "U": None}
SPEED = 200.0
OFFSET_M = 2000.0  # O's ADS-B positions are this far east of it


def _start(name: str) -> tuple[float, float]:
    k = list(AIRCRAFT).index(name) if name in AIRCRAFT else 20 + len(name)
    return -50_000.0, -100_000.0 + 30_000.0 * k


def _truth(names) -> pd.DataFrame:
    t = np.arange(0.0, 310.0, 10.0)
    frames = []
    for name in names:
        x0, y0 = _start(name)
        frames.append(pd.DataFrame({"target_id": name, "segment": 0, "time": t, "x": x0 + SPEED * t, "y": y0,
                                    "z": 9000.0, "vx": SPEED, "vy": 0.0, "vz": 0.0, "visible": True}))
    return pd.concat(frames, ignore_index=True)


def _adsb(senders: dict[str, str], span=(0.0, 300.0), offsets=None) -> pd.DataFrame:
    """One report per second per sender (target id -> address sent), exact positions plus offsets."""
    offsets = offsets or {}
    frames = []
    for name, address in senders.items():
        lo, hi = span if not isinstance(span, dict) else span.get(name, (0.0, 300.0))
        t = np.arange(lo, hi + 0.5, 1.0) + 0.25
        t = t[t <= 300.0]
        x0, y0 = _start(name)
        frames.append(pd.DataFrame({"time": t, "icao24": address, "x": x0 + SPEED * t + offsets.get(name, 0.0),
                                    "y": y0, "z": 9000.0, "sigma_m": 10.0, "callsign": f"CS{name}",
                                    "truth_id": name}))
    return pd.concat(frames, ignore_index=True)


def _track(track_id: int, name: str | None, times, *, labels=None, source="adsb", dx=50.0, where=None,
           status="confirmed") -> pd.DataFrame:
    """Rows of one track at ``times``: 50 m east of ``name``'s truth, or at ``where`` (x, y) for a
    false track; ``labels`` maps a time to its icao24 (unlisted: unlabelled)."""
    times = np.asarray(times, dtype=float)
    if name is not None:
        x0, y0 = _start(name)
        x, y = x0 + SPEED * times + dx, np.full(times.size, y0)
    else:
        x, y = np.full(times.size, where[0]), np.full(times.size, where[1])
    labels = labels or {}
    icao = [labels.get(float(t)) for t in times]
    return pd.DataFrame({"time": times, "track_id": track_id, "x": x, "y": y, "z": np.nan, "vx": SPEED,
                         "vy": 0.0, "status": status, "icao24": icao,
                         "identity_source": [source if a is not None else None for a in icao]})


def _from(t0, address, times=TIMES, until=np.inf):
    return {float(t): address for t in times if t0 <= t <= until}


def _scene():
    """Tracks, truth and ADS-B of the main case (the counts in the test are worked out from this)."""
    a_labels = _from(20.0, "aaa001")
    a_labels.update({t: "bbb002" for t in (200.0, 202.0, 204.0, 206.0, 208.0)})  # injected wrong label
    tracks = pd.concat([
        _track(1, "A", TIMES, labels=a_labels),  # identified at 20 s, 5 wrong rows
        _track(2, "B", TIMES[TIMES >= 10.0], labels=_from(40.0, "bbb002")),  # identified 30 s after first tracked
        _track(3, "C", TIMES, labels=_from(100.0, "ccc003")),  # late
        _track(4, "D", TIMES, labels=_from(20.0, "ddd004", until=60.0)),  # label lost after 60 s: unstable
        _track(5, "E", TIMES),  # never labelled
        _track(6, "F", TIMES[TIMES <= 40.0], labels=_from(10.0, "fff006")),  # track ends after 40 s
        _track(7, "O", TIMES),  # offset ADS-B, never labelled
        _track(8, "U", TIMES),  # no ADS-B
        _track(99, None, TIMES[(TIMES >= 100.0) & (TIMES <= 118.0)], labels=_from(0.0, "ccc003"),
               where=(0.0, 500_000.0)),  # false track with an ADS-B label: 10 wrong rows
        _track(98, None, TIMES, where=(0.0, 600_000.0)),  # false track, unlabelled
        _track(97, "B", TIMES[(TIMES >= 50.0) & (TIMES <= 58.0)], labels=_from(0.0, "bbb002"), dx=300.0),  # duplicate
        _track(96, None, TIMES[:3], labels=_from(0.0, "ccc003"), where=(0.0, 700_000.0), status="tentative"),
    ], ignore_index=True)
    senders = {name: address for name, address in AIRCRAFT.items() if address is not None}
    return tracks, _truth(AIRCRAFT), _adsb(senders, offsets={"O": OFFSET_M})


@pytest.fixture(scope="module")
def report():
    tracks, truth, adsb = _scene()
    return identification_report(tracks, truth, adsb, min_tracked_s=60.0)


def test_statuses_and_times_per_aircraft(report):
    frame = report.per_aircraft.set_index("target_id")
    assert list(frame.index) == ["A", "B", "C", "D", "E", "F", "O"]  # U sends no ADS-B: not equipped
    assert frame["status"].to_dict() == {
        "A": "identified", "B": "identified", "C": "late", "D": "unstable", "E": "not identified",
        "F": "not tracked long enough", "O": "not identified"}
    assert set(frame["status"]) == set(STATUSES)
    assert frame["icao24"].to_dict() == {n: AIRCRAFT[n] for n in frame.index}
    assert frame["callsign"].to_dict() == {n: f"CS{n}" for n in frame.index}
    np.testing.assert_array_equal(frame["first_tracked_s"], [0, 10, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(frame["tracked_s"], [298, 288, 298, 298, 298, 40, 298])
    np.testing.assert_array_equal(frame["tracked_long_enough"], [True] * 5 + [False, True])
    np.testing.assert_array_equal(frame["time_to_identify_s"], [20, 30, 100, 20, np.nan, 10, np.nan])
    np.testing.assert_array_equal(frame["n_rows"], [150, 145, 150, 150, 150, 21, 150])
    np.testing.assert_array_equal(frame["n_rows_after"], [120, 115, 120, 120, 120, 0, 120])
    np.testing.assert_allclose(frame["correct_fraction_after"], [115 / 120, 1.0, 100 / 120, 1 / 120, 0.0, np.nan, 0.0],
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(frame["wrong_label_rows"], [5, 0, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(frame["n_tracks"], [1] * 7)  # the duplicate track 97 is not B's


def test_faulty_adsb_is_listed_and_left_unidentified(report):
    faulty = report.adsb_faulty
    assert list(faulty["target_id"]) == ["O"]
    row = faulty.iloc[0]
    assert row["adsb_fault"] == "position offset"
    assert row["adsb_offset_m"] == pytest.approx(OFFSET_M, abs=1e-6)  # exact reports: the offset alone
    assert bool(row["left_unidentified"]) and row["adsb_labelled_rows"] == 0 and row["status"] == "not identified"
    others = report.per_aircraft.set_index("target_id").drop("O")
    assert others["adsb_fault"].isna().all() and (others["adsb_offset_m"] < 1e-6).all()
    assert any(line.startswith("O: faulty ADS-B, ADS-B positions 2000 m") and line.endswith("left unidentified")
               for line in report.findings)


def test_wrong_labels_and_totals(report):
    wrong = report.wrong_labels
    assert wrong[["track_id", "icao24", "target_id", "label_owner", "identity_source", "n_rows", "first_s",
                  "last_s"]].values.tolist() == [
        [99, "ccc003", None, "C", "adsb", 10, 100.0, 118.0],
        [1, "bbb002", "A", "B", "adsb", 5, 200.0, 208.0],
    ]
    totals = report.totals
    expected = {
        "equipped_aircraft": 7, "tracked_long_enough": 6, "identified": 2, "late": 1, "unstable": 1,
        "not_identified": 2, "not_tracked_long_enough": 1, "sound_tracked_long_enough": 5, "sound_identified": 3,
        "sound_label_held": 2,
        "adsb_faulty_aircraft": 1, "adsb_faulty_left_unidentified": 1,
        "median_time_to_identify_s": 25.0, "max_time_to_identify_s": 100.0,  # of A 20, B 30, C 100, D 20
        "track_rows": 1231, "associated_rows": 1066, "false_track_rows": 165,
        "labelled_rows": 422, "correct_label_rows": 402, "wrong_label_rows": 15, "wrong_label_tracks": 2,
        "wrong_label_aircraft": 3, "wrong_label_aircraft_ids": ["A", "B", "C"], "duplicate_label_rows": 5,
        "unjudged_label_rows": 0, "truth_objects": 8,
    }
    assert totals == expected
    assert report.acceptance == {
        "every sound equipped aircraft tracked long enough is identified": False,
        "no track row has a wrong label": False,
        "every aircraft with faulty ADS-B is left unidentified": True,
    }
    assert not report.passed
    assert report.dimension.startswith("horizontal")
    assert any("3 track rows ignored" in note for note in report.notes)  # the tentative track 96


def test_to_dict_is_json(report):
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))
    assert data["totals"]["wrong_label_rows"] == 15
    assert [row["status"] for row in data["per_aircraft"]][:2] == ["identified", "identified"]
    assert data["per_aircraft"][5]["correct_fraction_after"] is None  # F: no rows after 60 s
    assert data["adsb_faulty"][0]["target_id"] == "O" and data["passed"] is False


def test_rich_table_shows_totals_and_problems(report):
    console = Console(record=True, width=200, color_system=None)
    console.print(identification_table(report))
    text = console.export_text()
    for expected in ("ADS-B-equipped aircraft", "identified correctly", "2 of 6", "15 / 2 / 3", "25 / 100",
                     "1 (1)", "FAIL", "position offset (2000 m, left unidentified)", "not tracked long enough",
                     "false track", "unstable", "late"):
        assert expected in text, expected
    problem_rows = [line for line in text.splitlines() if line.strip().startswith(("│ A ", "│ B "))]
    assert len(problem_rows) == 1 and "│ A " in problem_rows[0]  # A has wrong rows; B is fine and not listed


def test_clean_run_passes_acceptance():
    """Every sound aircraft identified by 60 s and held, no wrong label, the offset aircraft unlabelled."""
    tracks = pd.concat([_track(1, "A", TIMES, labels=_from(8.0, "aaa001")),
                        _track(2, "B", TIMES, labels=_from(12.0, "bbb002")),
                        _track(7, "O", TIMES)], ignore_index=True)
    truth = _truth(["A", "B", "O"])
    adsb = _adsb({"A": "aaa001", "B": "bbb002", "O": "0ff007"}, offsets={"O": OFFSET_M})
    report = identification_report(tracks, truth, adsb)
    assert report.passed and all(report.acceptance.values())
    assert report.totals["identified"] == 2 and report.totals["not_identified"] == 1
    assert report.totals["median_time_to_identify_s"] == 10.0 and report.totals["max_time_to_identify_s"] == 12.0
    # the offset aircraft labelled with its own address: not left unidentified, and the verdict says so
    labelled = pd.concat([tracks[tracks["track_id"] != 7], _track(7, "O", TIMES, labels=_from(30.0, "0ff007"))])
    flagged = identification_report(labelled, truth, adsb)
    assert flagged.adsb_faulty["adsb_labelled_rows"].tolist() == [135]
    assert flagged.acceptance["every aircraft with faulty ADS-B is left unidentified"] is False
    assert flagged.acceptance["no track row has a wrong label"] is True  # its own address is no wrong label
    assert any("NOT left unidentified: 135 rows" in line for line in flagged.findings)


def test_wrong_identity_by_address_conflict():
    """W sends A's address (fewer reports than A): A owns it, W has a wrong identity and no label of its own;
    W's track labelled with it is wrong on W's rows, and the address's owner A is affected."""
    truth = _truth(["A", "W"])
    adsb = pd.concat([_adsb({"A": "aaa001"}), _adsb({"W": "aaa001"}, span=(0.0, 99.0))], ignore_index=True)
    tracks = pd.concat([_track(1, "A", TIMES, labels=_from(4.0, "aaa001")),
                        _track(2, "W", TIMES, labels=_from(50.0, "aaa001", until=98.0))], ignore_index=True)
    report = identification_report(tracks, truth, adsb)
    frame = report.per_aircraft.set_index("target_id")
    assert frame.loc["A", "status"] == "identified" and frame.loc["A", "adsb_fault"] is None
    assert frame.loc["W", "icao24"] is None and frame.loc["W", "status"] == "not identified"
    assert report.adsb_faulty[["target_id", "adsb_fault", "own_icao24", "sent_icao24", "adsb_labelled_rows",
                               "left_unidentified"]].values.tolist() == [["W", "wrong identity", None, "aaa001", 25,
                                                                          False]]
    assert report.wrong_labels[["track_id", "icao24", "target_id", "label_owner", "n_rows"]].values.tolist() == [
        [2, "aaa001", "W", "A", 25]]
    assert report.totals["wrong_label_aircraft_ids"] == ["A", "W"]


def test_own_address_from_aircraft_table():
    """W sends a made-up address: only its own address (the simulator's targets table) reveals the fault."""
    truth = _truth(["W"])
    adsb = _adsb({"W": "fed009"})
    tracks = _track(1, "W", TIMES, labels=_from(6.0, "fed009"))
    blind = identification_report(tracks, truth, adsb)
    assert blind.per_aircraft["status"].tolist() == ["identified"] and blind.adsb_faulty.empty
    told = identification_report(tracks, truth, adsb, aircraft=pd.DataFrame({"target_id": ["W"], "icao24": ["ABC008"]}))
    row = told.per_aircraft.iloc[0]
    assert (row["icao24"], row["status"], row["wrong_label_rows"]) == ("abc008", "not identified", 147)
    assert told.adsb_faulty[["adsb_fault", "own_icao24", "left_unidentified"]].values.tolist() == [
        ["wrong identity", "abc008", False]]


def test_bad_inputs_name_the_problem():
    tracks, truth, adsb = _scene()
    with pytest.raises(ValueError, match="adsb table: missing required column\\(s\\) truth_id"):
        identification_report(tracks, truth, adsb.drop(columns="truth_id"))
    with pytest.raises(ValueError, match="cutoff_m"):
        identification_report(tracks, truth, adsb, cutoff_m=0.0)

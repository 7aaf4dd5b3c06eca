"""Issue 9 acceptance on the recorded-trajectory windows: ADS-B identification of radar tracks.

Spec 001 (R13, R14) applied by ``skytrack track --adsb`` (:mod:`skytrack.app.identification`) and
scored by :func:`skytrack.analysis.identification.identification_report`.  Issue 9's acceptance:
"every ADS-B-equipped aircraft tracked for 1 minute is identified correctly, no track gets a wrong
label, the offset aircraft is left unidentified or flagged ... The same holds on the
recorded-trajectory benchmark windows with simulated ADS-B."

Windows: the recorded ones of ``benchmarks/vs_stonesoup.py`` (:data:`vs_stonesoup_windows.WINDOWS`:
the Swiss recording's 10-20 minute windows and the Paris tuning windows), each simulated as that
benchmark does (the window's scenario YAML with its seed, ``--start``/``--duration``, the same seed
for the noise) with an ``adsb`` section added (:mod:`skytrack.sim.adsb`):

* 1 s reports at a random phase per aircraft, 0.05 s jitter, ``sigma_m`` 12 m (``--sigma-m``,
  NACp 9-10), heights 15 m, velocities 1 m/s, 3 % of the reports lost (``--p-drop``), ground
  station at the radar with the radar's 250 km coverage;
* 80 % equipage (``--equipage``: exactly round(0.8 n) of the n recorded aircraft, drawn from
  the scenario seed);
* one faulty aircraft: ADS-B positions 2 km east of the truth (``offset_m: [2000, 0]``), with the
  nominal sigma_m.  It is the segment that the radar sees longest (ties: the smallest id), chosen
  on a first simulation of the window without the fault; it is made equipped.

The recorded aircraft have Mode S addresses, which the simulated radar's SSR reports on every
plot; the plots' ``mode_s`` column is emptied before tracking (``--keep-mode-s`` keeps it), so
every label comes from the spec 001 test between the radar tracks and ADS-B, not from the
track's own Mode S replies.  The recordings are bundled with the package
(``src/skytrack/scenarios/recorded/*.parquet``, in git), so a fresh checkout has them.

Printed per window: aircraft, equipped aircraft, the offset aircraft, the report's totals (sound
equipped aircraft tracked >= 60 s and how many were identified, late, unstable, not identified;
wrong-label rows and tracks; the faulty aircraft left unidentified; median and max time to
identify), the wrong labels by cause (on a track coasting after its aircraft's recorded segment ended
inside coverage, on a track that lost an aircraft still flying, on another aircraft's track) and the
three acceptance verdicts, with the machine and the date.  Track rows after the
window's end (the tracker's last output closes the scan in progress, up to one scan after the last
plot) are not scored: there is no truth there, and the report would count them as false tracks.  ``--json`` writes
everything, per-aircraft rows included.

Usage:  python benchmarks/identify_recorded.py [--windows swiss-0930,paris-1220] [--minutes 5]
                                               [--out FOLDER] [--json FILE]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import platform
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from machine import cpu_model, usable_cores  # benchmarks/machine.py
from vs_stonesoup_windows import WINDOWS, ScenarioSource, Window

#: the offset of the faulty aircraft's ADS-B positions (east, north), m
OFFSET_M = (2000.0, 0.0)


@dataclass(frozen=True)
class AdsbSettings:
    equipage: float = 0.8
    sigma_m: float = 12.0
    p_drop: float = 0.03
    interval_s: float = 1.0

    def section(self, coverage_m: float, faulty: str | None) -> dict:
        section = {"interval_s": self.interval_s, "jitter_s": 0.05, "sigma_m": self.sigma_m, "sigma_alt_m": 15.0,
                   "velocities": True, "sigma_velocity_mps": 1.0, "p_drop": self.p_drop,
                   "equipage": self.equipage, "coverage_m": coverage_m}
        if faulty is not None:
            section["aircraft"] = {faulty: {"equipped": True, "offset_m": list(OFFSET_M)}}
        return section


def recorded_windows() -> list[Window]:
    """The windows of vs_stonesoup_windows that fly recorded traffic."""
    return [w for w in WINDOWS if isinstance(w.source, ScenarioSource) and "--start" in w.source.simulate_args]


def _window_args(window: Window) -> tuple[str, float | None]:
    args = dict(zip(window.source.simulate_args[::2], window.source.simulate_args[1::2]))
    return args["--start"], float(args["--duration"]) if "--duration" in args else None


def simulate_window(window: Window, folder: Path, adsb: AdsbSettings, faulty: str | None, minutes: float | None):
    """Simulate ``window`` with the ADS-B section into ``folder``; returns the SimulationResult."""
    from skytrack.app.simulate import run_simulation

    source = window.source
    document = yaml.safe_load(source.scenario.read_text())
    if source.seed is not None:
        document["seed"] = int(source.seed)
    coverage = max(float(s["max_range_m"]) for s in document["sensors"])
    document["adsb"] = adsb.section(coverage, faulty)
    recorded = document.get("recorded") or {}
    if "path" in recorded:
        recorded["path"] = str((source.scenario.parent / recorded["path"]).resolve())
    folder.mkdir(parents=True, exist_ok=True)
    scenario = folder / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(document, sort_keys=False))
    start, duration = _window_args(window)
    if minutes is not None:
        duration = min(duration or 1e12, 60.0 * minutes)
    return run_simulation(scenario, seed=source.seed, start=start, duration=duration)


def longest_seen(result) -> str:
    """The target the radar sees longest (visible truth rows; ties: smallest id)."""
    truth = result.truth
    seen = truth[truth["visible"]].groupby("target_id")["time"].agg(lambda t: t.max() - t.min())
    seen = seen.sort_index(kind="stable")
    return str(seen.idxmax())


def run_window(window: Window, folder: Path, adsb: AdsbSettings, minutes: float | None, keep_mode_s: bool) -> dict:
    from skytrack.analysis.identification import identification_report
    from skytrack.app.run import run_tracking
    from skytrack.app.simulate import write_simulation
    from skytrack.io import read_adsb, read_sensors, read_tracks

    started = time.perf_counter()
    first = simulate_window(window, folder / "probe", adsb, None, minutes)
    faulty = longest_seen(first)
    result = simulate_window(window, folder, adsb, faulty, minutes)
    if not keep_mode_s:
        result.plots["mode_s"] = pd.array([None] * len(result.plots), dtype="str")
    write_simulation(result, folder)
    simulated = time.perf_counter() - started
    tracks_path = folder / "tracks.parquet"
    started = time.perf_counter()
    summary = run_tracking(folder / "plots.parquet", folder / "sensors.json", tracks_path,
                           adsb_path=folder / "adsb.parquet")
    tracked = time.perf_counter() - started
    sensors = read_sensors(folder / "sensors.json")
    adsb_reports = read_adsb(folder / "adsb.parquet", sensors=sensors)
    tracks = read_tracks(tracks_path)
    # the tracker's last output instant closes the scan in progress, up to one scan after the last
    # plot; no truth exists after the window's end to judge those rows (they would all be false tracks)
    end = float(result.truth["time"].max())
    scored = tracks[tracks["time"] <= end + 1e-9]
    report = identification_report(scored, result.truth, adsb_reports, aircraft=result.targets)
    aircraft = result.adsb_aircraft
    return {
        "window": window.name, "source": window.source.describe(), "duration_s": float(result.scenario.duration_s),
        "aircraft": int(len(result.targets)), "equipped": int(aircraft["equipped"].sum()),
        "offset_aircraft": faulty, "plots": int(summary.plots), "adsb_reports": int(len(adsb_reports)),
        "track_rows": int(len(tracks)), "track_rows_after_window_end": int(len(tracks) - len(scored)),
        "simulate_s": simulated, "track_and_label_s": tracked, "labelling": summary.identification,
        "totals": report.totals, "acceptance": report.acceptance, "passed": report.passed,
        "wrong_label_causes": wrong_label_causes(report.wrong_labels, result.truth),
        "findings": list(report.findings), "report": report.to_dict(),
    }


#: why a wrong label happened (:func:`wrong_label_causes`)
CAUSES = {
    "after_truth_end": "on a track coasting after its labelled aircraft's recorded segment ended inside coverage",
    "track_lost": "on a track more than the gate from its labelled aircraft, which still flies (track lost it)",
    "other_aircraft": "on a track of another aircraft",
}


def wrong_label_causes(wrong_labels: pd.DataFrame, truth: pd.DataFrame) -> dict[str, dict[str, int]]:
    """Groups and rows of the report's wrong labels by cause (:data:`CAUSES`).  A recorded aircraft's
    truth ends where its recorded segment ends, also inside radar coverage: its plots stop at once
    and its track coasts a few scans with the label it had."""
    end = truth.groupby("target_id")["time"].max()
    owner_end = wrong_labels["label_owner"].map(end).to_numpy(float)
    on_no_object = wrong_labels["target_id"].isna().to_numpy()
    cause = np.where(~on_no_object, "other_aircraft",
                     np.where(wrong_labels["first_s"].to_numpy(float) >= owner_end - 1e-6, "after_truth_end",
                              "track_lost"))
    rows = wrong_labels["n_rows"].to_numpy(int)
    return {name: {"groups": int((cause == name).sum()), "rows": int(rows[cause == name].sum())} for name in CAUSES}


def _fmt(value, unit: str = "") -> str:
    return "-" if value is None or (isinstance(value, float) and not np.isfinite(value)) else f"{value:.0f}{unit}"


def print_window(row: dict) -> None:
    t = row["totals"]
    print(f"\n{row['window']}: {row['source']}")
    print(f"  {row['duration_s']:.0f} s, {row['aircraft']} aircraft ({row['equipped']} with ADS-B), "
          f"{row['plots']} plots, {row['adsb_reports']} ADS-B reports, {row['track_rows']} track rows "
          f"({row['track_rows_after_window_end']} after the window's end, not scored); "
          f"offset aircraft {row['offset_aircraft']}; "
          f"simulated in {row['simulate_s']:.1f} s, tracked and labelled in {row['track_and_label_s']:.1f} s")
    print(f"  sound equipped aircraft tracked >= 60 s: {t['sound_tracked_long_enough']}, identified "
          f"{t['sound_identified']} (all equipped: identified {t['identified']}, late {t['late']}, unstable "
          f"{t['unstable']}, not identified {t['not_identified']}, not tracked long enough "
          f"{t['not_tracked_long_enough']})")
    print(f"  wrong labels: {t['wrong_label_rows']} rows on {t['wrong_label_tracks']} tracks "
          f"({t['wrong_label_aircraft']} aircraft); label rows correct {t['correct_label_rows']} of "
          f"{t['labelled_rows']}, duplicates {t['duplicate_label_rows']}")
    for name, count in row["wrong_label_causes"].items():
        if count["groups"]:
            print(f"    {count['rows']} rows ({count['groups']} track/label pairs) {CAUSES[name]}")
    print(f"  faulty ADS-B aircraft: {t['adsb_faulty_aircraft']}, left unidentified "
          f"{t['adsb_faulty_left_unidentified']}; time to identify median {_fmt(t['median_time_to_identify_s'], ' s')}, "
          f"max {_fmt(t['max_time_to_identify_s'], ' s')}")
    for claim, ok in row["acceptance"].items():
        print(f"  [{'pass' if ok else 'FAIL'}] {claim}")
    for line in row["findings"]:
        print(f"    - {line}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--windows", help="comma-separated window names (default: every recorded window)")
    parser.add_argument("--minutes", type=float, help="cut every window to this many minutes")
    parser.add_argument("--equipage", type=float, default=AdsbSettings.equipage)
    parser.add_argument("--sigma-m", type=float, default=AdsbSettings.sigma_m)
    parser.add_argument("--p-drop", type=float, default=AdsbSettings.p_drop)
    parser.add_argument("--keep-mode-s", action="store_true", help="keep the radar plots' Mode S addresses")
    parser.add_argument("--out", type=Path, help="folder for the windows' files (default: a temporary one)")
    parser.add_argument("--json", type=Path, help="write every window's result as JSON")
    args = parser.parse_args(argv)
    available = {w.name: w for w in recorded_windows()}
    names = list(available) if not args.windows else [n.strip() for n in args.windows.split(",") if n.strip()]
    unknown = [n for n in names if n not in available]
    if unknown:
        parser.error(f"unknown window(s) {', '.join(unknown)}; recorded windows: {', '.join(available)}")
    adsb = AdsbSettings(equipage=args.equipage, sigma_m=args.sigma_m, p_drop=args.p_drop)
    import skytrack

    print(f"issue 9 ADS-B identification on the recorded windows, {dt.date.today().isoformat()}, {cpu_model()}, "
          f"{usable_cores()} usable cores, Python {platform.python_version()}, numpy {np.__version__}, "
          f"skytrack {getattr(skytrack, '__version__', '?')}")
    print(f"ADS-B: equipage {adsb.equipage:.0%}, sigma {adsb.sigma_m:g} m, every {adsb.interval_s:g} s, "
          f"{adsb.p_drop:.0%} lost, one aircraft {OFFSET_M[0]:.0f} m off; radar Mode S "
          f"{'kept' if args.keep_mode_s else 'removed (labels from the spec 001 test only)'}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="identify_recorded_") as scratch:
        base = args.out if args.out is not None else Path(scratch)
        for name in names:
            row = run_window(available[name], base / name, adsb, args.minutes, args.keep_mode_s)
            print_window(row)
            sys.stdout.flush()
            rows.append(row)
    passed = sum(row["passed"] for row in rows)
    print(f"\n{passed} of {len(rows)} windows pass every acceptance claim")
    if args.json is not None:
        args.json.write_text(json.dumps({"date": dt.date.today().isoformat(), "cpu": cpu_model(),
                                         "windows": rows}, indent=2, default=str))
        print(f"wrote {args.json}")
    return 0 if passed == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())

"""Windows of ``benchmarks/vs_stonesoup.py``: where each window's plots, truth and sensors.json come from.

A window is a folder with ``plots.parquet`` (or ``.csv``), ``truth.parquet`` (or ``.csv``)
and ``sensors.json`` in the docs/formats.md layout.  :data:`WINDOWS` lists the named
windows; each has a role (``tune``: Stone Soup's parameters were chosen on it; ``report``:
the benchmark's reported windows; ``tune-skytrack``: skytrack's own settings were chosen on
it; ``check``: run by name only) and a source:

* :class:`ScenarioSource`: ``skytrack simulate SCENARIO --seed SEED -o FOLDER`` on a copy of
  the scenario YAML whose ``seed`` (trajectories) is replaced by SEED, so each seed gives
  other aircraft, other noise and other clutter.  ``simulate_args`` is passed on to
  ``skytrack simulate``: the windows on recorded trajectories are entries with
  ``("--start", UTC, "--duration", SECONDS)`` on a scenario whose ``recorded`` section names
  the recording (``--trajectories FILE`` would name another one).
* :class:`FolderSource`: a folder made beforehand (by ``skytrack simulate`` or any tool
  that writes the docs/formats.md layout), used as it is.

On the command line, ``--windows`` takes names from :data:`WINDOWS`, folders, or scenario
YAML files (simulated with the seed written in them).
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import yaml

SCENES = Path(__file__).parent / "scenes_vs_stonesoup"


@dataclass(frozen=True)
class ScenarioSource:
    """Simulate a scenario YAML with ``seed`` for both its trajectories and its noise."""

    scenario: Path
    seed: int | None = None
    """None: the scenario's own seed, and the scenario's noise"""
    simulate_args: tuple[str, ...] = ()
    overrides: tuple[tuple[str, object], ...] = ()
    """``("sensors.0.clutter_per_scan", 0.0)``: dotted key paths of the YAML replaced in the copy"""

    def describe(self) -> str:
        seed = "" if self.seed is None else f", seed {self.seed}"
        extra = f", {' '.join(self.simulate_args)}" if self.simulate_args else ""
        changed = "".join(f", {key} = {value}" for key, value in self.overrides)
        return f"skytrack simulate {self.scenario.name}{seed}{changed}{extra}"

    def prepare(self, folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        scenario = self.scenario
        seed_args: list[str] = []
        if self.seed is not None or self.overrides:
            document = yaml.safe_load(self.scenario.read_text())
            if self.seed is not None:
                document["seed"] = int(self.seed)
                seed_args = ["--seed", str(self.seed)]
            for key, value in self.overrides:
                *parents, last = key.split(".")
                node = document
                for part in parents:
                    node = node[int(part)] if isinstance(node, list) else node[part]
                node[int(last) if isinstance(node, list) else last] = value
            recorded = document.get("recorded") or {}
            if "path" in recorded:  # relative to the original file, which the copy is not next to
                recorded["path"] = str((self.scenario.parent / recorded["path"]).resolve())
            scenario = folder / "scenario.yaml"
            scenario.write_text(yaml.safe_dump(document, sort_keys=False))
        command = [sys.executable, "-m", "skytrack", "simulate", str(scenario), "-o", str(folder), *seed_args,
                   *self.simulate_args]
        done = subprocess.run(command, check=False, capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(command)} failed:\n{done.stdout}\n{done.stderr}")
        return folder


@dataclass(frozen=True)
class FolderSource:
    """A window folder that exists already."""

    folder: Path

    def describe(self) -> str:
        return f"folder {self.folder}"

    def prepare(self, folder: Path) -> Path:
        return self.folder


@dataclass(frozen=True)
class Window:
    name: str
    role: str
    """``tune``, ``report`` or ``check`` (run by name only)"""
    source: ScenarioSource | FolderSource
    notes: str = field(default="", compare=False)


#: The named windows.  Tuning and reported windows share the scenario's design but not a
#: seed: Stone Soup was never tuned on a reported window.
WINDOWS: tuple[Window, ...] = (
    Window("tune-1", "tune", ScenarioSource(SCENES / "tuning.yaml", 2001)),
    Window("tune-2", "tune", ScenarioSource(SCENES / "tuning.yaml", 2002)),
    Window("report-1", "report", ScenarioSource(SCENES / "reported.yaml", 1001)),
    Window("report-2", "report", ScenarioSource(SCENES / "reported.yaml", 1002)),
    Window("report-3", "report", ScenarioSource(SCENES / "reported.yaml", 1003)),
    # recorded aircraft as truth (docs/recorded.md): the windows of the Swiss recording with
    # at least 30 aircraft in coverage at every instant; the noise seed differs per window
    *(Window(f"swiss-{start[:2]}{start[3:5]}", "report",
             ScenarioSource(SCENES / "recorded_switzerland.yaml", seed,
                            ("--start", f"2018-08-01T{start}:00Z", "--duration", str(minutes * 60))))
      for start, minutes, seed in (("09:30", 10, 3001), ("11:20", 20, 3002), ("11:40", 20, 3003),
                                   ("13:40", 10, 3004))),
    # recorded traffic around Paris: tuning windows of skytrack's own settings (the IMM model set),
    # never reported and not used by --tune
    *(Window(f"paris-{start[:2]}{start[3:5]}", "tune-skytrack",
             ScenarioSource(SCENES / "recorded_paris.yaml", seed,
                            ("--start", f"2021-10-07T{start}:00Z", "--duration", str(minutes * 60))))
      for start, minutes, seed in (("12:20", 15, 4001), ("13:30", 15, 4002))),
    # no clutter: checks the Stone Soup side's conversion to the tracks layout (its position
    # RMSE should be near the radar's cross-range error, 125 km x 0.1 deg = 218 m at mid range)
    Window("check-clutter-free", "check",
           ScenarioSource(SCENES / "tuning.yaml", 2001, overrides=(("sensors.0.clutter_per_scan", 0.0),))),
)


def by_role(role: str) -> list[Window]:
    return [w for w in WINDOWS if w.role == role]


def parse_windows(text: str) -> list[Window]:
    """``--windows``: comma-separated names of :data:`WINDOWS`, folders or scenario files."""
    known = {w.name: w for w in WINDOWS}
    windows = []
    for token in (t.strip() for t in text.split(",")):
        if not token:
            continue
        path = Path(token)
        if token in known:
            windows.append(known[token])
        elif path.is_dir():
            windows.append(Window(path.name or token, "report", FolderSource(path.resolve())))
        elif path.suffix in (".yaml", ".yml") and path.is_file():
            windows.append(Window(path.stem, "report", ScenarioSource(path.resolve())))
        else:
            raise SystemExit(f"--windows: {token!r} is neither a window name ({', '.join(known)}), "
                             "a folder nor a scenario YAML file")
    return windows


def table_file(folder: Path, stem: str) -> Path:
    """``folder/stem.parquet`` or ``.csv``/``.csv.gz`` (the first that exists)."""
    for suffix in (".parquet", ".pq", ".csv", ".csv.gz"):
        if (folder / (stem + suffix)).exists():
            return folder / (stem + suffix)
    raise SystemExit(f"{folder}: no {stem}.parquet or {stem}.csv")

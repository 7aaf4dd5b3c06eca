"""End-to-end speed of the ``skytrack track`` command (a benchmark, not a test).

1. Builds, once, a large plots file and its sensors.json in ``--data-dir`` (reused by later
   runs): the bundled demo scenario scaled with :func:`skytrack.sim.scale_traffic` to
   ``--aircraft`` random aircraft, all airborne from the start (as in
   ``benchmarks/throughput.py``), simulated in pieces of ``--piece-s`` seconds so that memory
   stays small.  Piece k draws a new traffic sample (scenario seed + k) and is shifted by
   k pieces in time, so the file is in time order and the radar's antenna phase runs on;
   at every piece boundary the whole traffic is replaced (all tracks end, new ones start).
   Each piece is validated and written with :func:`skytrack.io.write_plots`, the pieces are
   joined into one Parquet file (one row group per piece) and the same rows are written as
   CSV.  The last piece is cut so that the file has exactly ``--plots`` plots.
2. Times the whole command ``skytrack track plots.parquet --sensors sensors.json -o
   tracks.parquet`` as a child process, ``--runs`` times: wall time (start-up, reading,
   tracking and writing included), plots per second and the child's peak resident memory
   (``os.wait4``).  Then the peak memory of single runs at two chunk sizes
   (``--memory-chunks``), for CSV and Parquet input: memory should follow the chunk size,
   not the file size.
3. Times ``skytrack --help`` (``--help-runs`` times).
4. Prints the machine, the date and the figures (medians; every run listed).  The first
   run after a change of the compiled kernels also fills their cache; the median of three
   runs leaves it out.

Children run on one thread of each pool: OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS=1 (pyarrow
sizes its CPU pool from OMP_NUM_THREADS), and with ``PYTHONDONTWRITEBYTECODE`` removed from
their environment: Python caches skytrack's bytecode as it does for an installed package
(pip compiles it at install), instead of compiling every module at each start (about 0.3 s
in an environment that sets the variable).  Use ``--plots 500000`` for a quick run.

Usage:  python benchmarks/end_to_end.py [--plots 5000000] [--data-dir DIR] [--runs 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ONE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
os.environ.update(ONE_THREAD)  # the build in this process too

sys.path.insert(0, str(Path(__file__).parent))
from machine import cpu_model, usable_cores, versions  # noqa: E402  (benchmarks/machine.py)
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

BUILD_VERSION = 1  # bump when the way the file is built changes (old folders are then rebuilt)


# ---------------------------------------------------------------------------------- data
def data_folder(root: Path, plots: int, aircraft: int, piece_s: float, seed: int) -> Path:
    return root / f"demo-{aircraft}ac-{plots}plots-{piece_s:g}s-seed{seed}-v{BUILD_VERSION}"


def build(folder: Path, plots: int, aircraft: int, piece_s: float, seed: int, console: Console) -> dict:
    """Simulate and write plots.parquet, plots.csv and sensors.json into ``folder`` (once)."""
    marker = folder / "build.json"
    if marker.exists():
        info = json.loads(marker.read_text())
        console.print(f"using the plots built earlier in {folder}")
        return info
    import numpy as np
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    from skytrack.io import write_plots, write_sensors
    from skytrack.sim import load_scenario, scale_traffic, simulate

    folder.mkdir(parents=True, exist_ok=True)
    base = scale_traffic(load_scenario("demo"), aircraft)
    base = dataclasses.replace(base, traffic=dataclasses.replace(base.traffic, start_time_s=(0.0, 0.0)),
                               duration_s=piece_s, seed=seed, adsb=None)  # radar plots only
    parquet_path, csv_path = folder / "plots.parquet", folder / "plots.csv"
    partial = folder / "plots.parquet.partial"
    started = time.perf_counter()
    written = false_plots = 0
    writer = schema = sensors = None
    piece = 0
    try:
        while written < plots:
            result = simulate(dataclasses.replace(base, seed=seed + piece))
            sensors = result.sensors
            period = sensors.sensors[0].scan_period_s
            if abs(piece_s / period - round(piece_s / period)) > 1e-9:
                raise SystemExit(f"--piece-s must be a multiple of the scan period ({period:g} s)")
            frame = result.plots.iloc[: plots - written].copy()
            frame["time"] += piece * piece_s
            if "scan" in frame.columns:
                frame["scan"] += piece * int(round(piece_s / period))
            if "truth_id" in frame.columns:  # the aircraft of each piece are others
                ids = frame["truth_id"].astype(str)
                frame["truth_id"] = np.where(ids == "", "", f"p{piece:04d}-" + ids)
                false_plots += int((ids == "").sum())
            part = write_plots(frame, folder / f"part{piece:04d}.parquet", sensors=sensors)
            table = pq.read_table(part)
            if writer is None:
                schema = table.schema
                writer = pq.ParquetWriter(partial, schema)
            writer.write_table(table.cast(schema))
            part.unlink()
            written += len(frame)
            piece += 1
            console.print(f"  piece {piece}: {written:,} / {plots:,} plots ({time.perf_counter() - started:.0f} s)")
    finally:
        if writer is not None:
            writer.close()
    partial.replace(parquet_path)
    write_sensors(sensors, folder / "sensors.json")
    source = pq.ParquetFile(parquet_path)
    with pcsv.CSVWriter(csv_path, source.schema_arrow) as csv_writer:
        for batch in source.iter_batches(batch_size=200_000):
            csv_writer.write_batch(batch)
    info = {
        "plots": written, "false_plots": false_plots, "aircraft_per_piece": aircraft + len(base.targets),
        "pieces": piece, "piece_s": piece_s, "duration_s": piece * piece_s, "seed": seed,
        "build_s": time.perf_counter() - started,
    }
    marker.write_text(json.dumps(info, indent=2) + "\n")
    return info


# ---------------------------------------------------------------------------- measuring
def skytrack_command() -> list[str]:
    script = Path(sys.executable).parent / "skytrack"
    if script.exists():
        return [str(script)]
    found = shutil.which("skytrack")
    return [found] if found else [sys.executable, "-m", "skytrack"]


def run_child(command: list[str], log: Path) -> tuple[float, float]:
    """Run ``command``; returns (wall seconds, peak RSS in MiB) of that child alone."""
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"} | ONE_THREAD
    with open(log, "wb") as output:
        started = time.perf_counter()
        child = subprocess.Popen(command, stdout=output, stderr=subprocess.STDOUT, env=env)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - started
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed (exit {child.returncode}):\n{log.read_text()[-3000:]}")
    return wall, usage.ru_maxrss / 1024.0  # ru_maxrss is in KiB on Linux


def track_command(plots: Path, sensors: Path, out: Path, chunk_rows: int | None) -> list[str]:
    command = skytrack_command() + ["track", str(plots), "--sensors", str(sensors), "-o", str(out)]
    return command + (["--chunk-rows", str(chunk_rows)] if chunk_rows else [])


# ------------------------------------------------------------------------------- report
def machine() -> dict:
    model, usable = cpu_model(), usable_cores()
    found = versions(("skytrack", "numpy", "pandas", "pyarrow", "numba"))
    return {"cpu": model, "cores": os.cpu_count(), "usable": usable, "system": platform.platform(),
            "python": platform.python_version(), "versions": found}


def mib(path: Path) -> str:
    return f"{path.stat().st_size / 2**20:,.0f} MiB"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plots", type=int, default=5_000_000, help="plots in the built file")
    parser.add_argument("--aircraft", type=int, default=1000, help="random aircraft of the scaled demo")
    parser.add_argument("--piece-s", type=float, default=600.0, help="seconds simulated per piece")
    parser.add_argument("--seed", type=int, default=20211007, help="scenario seed of the first piece")
    parser.add_argument("--data-dir", type=Path, default=Path(tempfile.gettempdir()) / "skytrack-end-to-end",
                        help="folder of the built files (reused when present)")
    parser.add_argument("--runs", type=int, default=3, help="timed runs of the Parquet command (median)")
    parser.add_argument("--memory-chunks", default="50000,500000", help="two --chunk-rows values for the memory runs")
    parser.add_argument("--help-runs", type=int, default=5, help="timed runs of `skytrack --help` (median)")
    args = parser.parse_args()
    console = Console(width=150)
    chunk_sizes = [int(c) for c in args.memory_chunks.split(",") if c.strip()]

    folder = data_folder(args.data_dir, args.plots, args.aircraft, args.piece_s, args.seed)
    info = build(folder, args.plots, args.aircraft, args.piece_s, args.seed, console)
    plots_parquet, plots_csv, sensors = folder / "plots.parquet", folder / "plots.csv", folder / "sensors.json"
    out = folder / "out"
    out.mkdir(exist_ok=True)
    n = info["plots"]

    rows = []
    console.print(f"timing `skytrack track` on {n:,} plots, {args.runs} run(s) ...")
    walls, peaks = [], []
    for run in range(args.runs):
        wall, peak = run_child(track_command(plots_parquet, sensors, out / "tracks.parquet", None), out / "track.log")
        walls.append(wall)
        peaks.append(peak)
        console.print(f"  run {run + 1}: {wall:.2f} s, {n / wall:,.0f} plots/s, peak RSS {peak:,.0f} MiB")
    rows.append(("track, Parquet in and out", "parquet", "default", walls, peaks))
    for fmt, path in (("csv", plots_csv), ("parquet", plots_parquet)):
        for chunk in chunk_sizes:
            wall, peak = run_child(track_command(path, sensors, out / f"tracks_{fmt}.parquet", chunk), out / "track.log")
            console.print(f"  {fmt} input, --chunk-rows {chunk:,}: {wall:.2f} s, peak RSS {peak:,.0f} MiB")
            rows.append((f"memory: {fmt.upper()} in, Parquet out", fmt, f"{chunk:,}", [wall], [peak]))
    help_walls = []
    for _ in range(args.help_runs):
        wall, _peak = run_child(skytrack_command() + ["--help"], out / "help.log")
        help_walls.append(wall)

    host = machine()
    console.print()
    console.print(f"skytrack end-to-end benchmark, {dt.datetime.now(dt.timezone.utc):%Y-%m-%d %H:%M} UTC")
    console.print(f"machine: {host['cpu']}, {host['cores']} cores ({host['usable']} usable); {host['system']}; "
                  f"Python {host['python']}; " + ", ".join(f"{k} {v}" for k, v in host["versions"].items()))
    console.print(f"children: {', '.join(f'{k}=1' for k in ONE_THREAD)}; command: {' '.join(skytrack_command())}")
    console.print(
        f"input: {n:,} plots ({info['false_plots']:,} false) of the demo radar scaled to "
        f"{info['aircraft_per_piece']:,} aircraft, {info['pieces']} pieces of {info['piece_s']:g} s "
        f"({info['duration_s']:,.0f} s); plots.parquet {mib(plots_parquet)}, plots.csv {mib(plots_csv)}"
    )
    table = Table(title="skytrack track, whole command (start-up, reading, tracking and writing included)")
    for column in ("measurement", "chunk rows", "runs", "wall time (median)", "plots/s", "peak RSS", "every run"):
        table.add_column(column, justify="right" if column not in ("measurement", "every run") else "left")
    for name, _fmt, chunk, walls, peaks in rows:
        median = statistics.median(walls)
        table.add_row(name, chunk, str(len(walls)), f"{median:.2f} s", f"{n / median:,.0f}",
                      f"{max(peaks):,.0f} MiB", ", ".join(f"{w:.2f} s" for w in walls))
    median_help = statistics.median(help_walls)
    table.add_row("skytrack --help", "", str(len(help_walls)), f"{median_help:.3f} s", "", "",
                  ", ".join(f"{w:.3f} s" for w in help_walls))
    console.print(table)
    console.print("[dim]A run after the compiled kernels changed also compiles them into their cache (numba); "
                  "the median of the runs leaves such a run out when there are 3 or more.[/]")


if __name__ == "__main__":
    main()

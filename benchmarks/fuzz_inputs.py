"""Fuzz suite of the tracker's inputs (issue 6, item 8): run malformed files, classify outcomes.

Usage: python benchmarks/fuzz_inputs.py [--cases N] [--seed S] [--workers W] [--failures FILE]
       python benchmarks/fuzz_inputs.py --replay FILE   (re-runs the cases a failure file lists)

Each case (built by ``fuzz_mutations.make_case``) is written to a temporary folder and run
through :func:`skytrack.app.run.run_tracking` in-process under a 10 s alarm.  Its outcome is
one of :data:`OUTCOMES`: ``ok-error`` (a one-line ``ValueError``/``InputError`` naming the
file), ``ok-skip`` (lenient mode skipped and counted rows), ``ok-processed``, or a failure:
``crash`` (any other exception, or an error that does not name the file or spans lines),
``hang`` (over the time limit) or ``silent-loss`` (rows read plus rows skipped differ from
the rows in the file).  Totals per family and outcome are printed with the machine and date;
every failure (family, seed, index, mutation, exception) goes to a JSON file for replay.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # sibling modules when imported from tests

from fuzz_mutations import FAMILIES, BaseInputs, FuzzCase, make_base_inputs, make_case  # noqa: E402
from machine import cpu_model, usable_cores  # noqa: E402

OUTCOMES = ("ok-error", "ok-skip", "ok-processed", "crash", "hang", "silent-loss")
FAILURES = ("crash", "hang", "silent-loss")
TIME_LIMIT_S = 10.0


class CaseTimeout(BaseException):
    """Raised by the alarm; a BaseException so that no ``except Exception`` in the code under test hides it."""


@dataclass
class CaseResult:
    outcome: str
    detail: str
    case: FuzzCase

    def failure_record(self) -> dict:
        return {**self.case.replay, "outcome": self.outcome, "exception": self.detail}


def _on_alarm(signum, frame):
    raise CaseTimeout()


def classify_error(error: BaseException, case: FuzzCase) -> tuple[str, str]:
    """An error is acceptable when it is a ValueError whose message is one line naming the file at fault."""
    from skytrack.io import InputError

    text = str(error)
    detail = f"{type(error).__module__}.{type(error).__qualname__}: {text[:300]}"
    if not isinstance(error, ValueError):
        return "crash", detail + "\n" + "".join(traceback.format_tb(error.__traceback__)[-3:])
    named = case.plots_name in text or "sensors.json" in text
    if "\n" in text.strip() or not named:
        kind = "InputError" if isinstance(error, InputError) else "ValueError"
        why = "spans lines" if named else "does not name the file"
        return "crash", f"{kind} that {why}: {detail}"
    return "ok-error", detail


def classify_summary(summary, case: FuzzCase) -> tuple[str, str]:
    """Rows read plus rows skipped must be the rows in the file."""
    skipped = summary.report.rows_skipped if summary.report is not None else 0
    read = summary.report.rows_read if summary.report is not None else summary.plots
    detail = f"{summary.plots} plots tracked, {skipped} skipped, {case.rows_in_file} rows in the file"
    if summary.plots + skipped != case.rows_in_file or read != case.rows_in_file:
        return "silent-loss", detail
    return ("ok-skip" if skipped else "ok-processed"), detail


def run_case(case: FuzzCase, folder: Path) -> CaseResult:
    from skytrack.app.run import run_tracking

    plots, sensors, out = folder / case.plots_name, folder / "sensors.json", folder / "tracks.parquet"
    plots.write_bytes(case.plots_bytes)
    sensors.write_bytes(case.sensors_bytes)
    previous = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT_S)
    try:
        summary = run_tracking(plots, sensors, out, lenient=case.lenient, chunk_rows=case.chunk_rows)
        signal.setitimer(signal.ITIMER_REAL, 0)
        outcome, detail = classify_summary(summary, case)
    except CaseTimeout:
        outcome, detail = "hang", f"no result after {TIME_LIMIT_S:g} s"
    except Exception as error:  # noqa: BLE001 -- the classifier's job is to sort every exception
        signal.setitimer(signal.ITIMER_REAL, 0)
        outcome, detail = classify_error(error, case)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        for path in (plots, sensors, out):
            path.unlink(missing_ok=True)
    return CaseResult(outcome, detail, case)


_BASE: BaseInputs | None = None


def base_inputs() -> BaseInputs:
    """The valid inputs, simulated once per process; the valid run is tracked once first, untimed,
    so that compiling the tracker's kernels (about 30 s on a fresh checkout, whose numba cache
    is empty) is not counted as a hang of the first cases."""
    global _BASE
    if _BASE is None:
        from skytrack.app.run import run_tracking

        with tempfile.TemporaryDirectory() as folder:
            _BASE = make_base_inputs(folder)
            plots, sensors = Path(folder) / "warm-up.parquet", Path(folder) / "warm-up.json"
            plots.write_bytes(_BASE.parquet_bytes)
            sensors.write_text(json.dumps(_BASE.sensors))
            run_tracking(plots, sensors, Path(folder) / "warm-up-tracks.parquet")
    return _BASE


def run_cases(family: str, seed: int, indices: range) -> list[CaseResult]:
    """Run cases ``indices`` of a family; the result keeps only the failures' cases in full."""
    import warnings

    base = base_inputs()
    results = []
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unit and repeat warnings are expected on malformed inputs
        for index in indices:
            results.append(run_case(make_case(base, family, seed, index), Path(folder)))
    return results


def _tally(family: str, seed: int, start: int, stop: int) -> tuple[str, Counter, list[dict]]:
    results = run_cases(family, seed, range(start, stop))
    counts = Counter(result.outcome for result in results)
    return family, counts, [result.failure_record() for result in results if result.outcome in FAILURES]


def run_fuzz(cases: int, seed: int, workers: int, batch: int = 250) -> tuple[dict[str, Counter], list[dict]]:
    """``cases`` cases spread evenly over the families, run in ``workers`` processes."""
    per_family = -(-cases // len(FAMILIES))
    jobs = [(family, seed, start, min(start + batch, per_family))
            for family in FAMILIES for start in range(0, per_family, batch)]
    totals = {family: Counter() for family in FAMILIES}
    failures: list[dict] = []
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for done, (family, counts, failed) in enumerate(pool.map(_tally, *zip(*jobs)), 1):
            totals[family].update(counts)
            failures.extend(failed)
            for record in failed:  # at once, so that a long run can be looked into while it goes on
                print(f"  failure: {json.dumps(record)}", file=sys.stderr, flush=True)
            print(f"  {done}/{len(jobs)} batches, {len(failures)} failures so far", file=sys.stderr, flush=True)
    return totals, failures


def format_totals(totals: dict[str, Counter]) -> str:
    width = max(map(len, FAMILIES)) + 2
    lines = ["family".ljust(width) + "".join(f"{name:>14}" for name in OUTCOMES) + f"{'total':>10}"]
    overall = Counter()
    for family, counts in totals.items():
        overall.update(counts)
        lines.append(family.ljust(width) + "".join(f"{counts[name]:>14}" for name in OUTCOMES)
                     + f"{sum(counts.values()):>10}")
    lines.append("all".ljust(width) + "".join(f"{overall[name]:>14}" for name in OUTCOMES)
                 + f"{sum(overall.values()):>10}")
    return "\n".join(lines)


def replay(path: Path) -> None:
    base = base_inputs()
    for record in json.loads(path.read_text())["failures"]:
        case = make_case(base, record["family"], record["seed"], record["index"])
        with tempfile.TemporaryDirectory() as folder:
            result = run_case(case, Path(folder))
        print(f"{record['family']} seed {record['seed']} index {record['index']}: {result.outcome} -- "
              f"{case.mutation} -- {result.detail}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=usable_cores())
    parser.add_argument("--failures", type=Path, default=Path("fuzz_failures.json"))
    parser.add_argument("--replay", type=Path)
    args = parser.parse_args(argv)
    if args.replay:
        replay(args.replay)
        return 0
    started = time.perf_counter()
    totals, failures = run_fuzz(args.cases, args.seed, args.workers)
    wall = time.perf_counter() - started
    print(f"skytrack input fuzz: {sum(sum(c.values()) for c in totals.values())} cases, seed {args.seed}, "
          f"{wall:.0f} s wall on {args.workers} workers")
    print(f"machine: {cpu_model()}, {usable_cores()} cores, {os.uname().sysname}; "
          f"date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC")
    print(format_totals(totals))
    args.failures.write_text(json.dumps({"seed": args.seed, "cases": args.cases, "failures": failures}, indent=1))
    print(f"{len(failures)} failing cases written to {args.failures}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

"""What the benchmarks print about the machine: CPU model, cores, library versions."""

from __future__ import annotations

import os
from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo ("unknown CPU" elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


def usable_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def versions(names: tuple[str, ...]) -> dict[str, str]:
    """``__version__`` of each importable package among ``names``."""
    found = {}
    for name in names:
        try:
            found[name] = __import__(name).__version__
        except ImportError:
            continue
    return found

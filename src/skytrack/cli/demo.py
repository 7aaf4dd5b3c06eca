"""Printing of ``skytrack demo``; the pipeline itself is :mod:`skytrack.app.demo`."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table


def demo_passed(result) -> bool:
    """Whether every pass/fail check of the demo passed."""
    checks = result.checks
    return bool(checks["every_aircraft_in_coverage_2min_tracked"] and checks["position_rmse_below_cross_range_sigma"])


def _metres(value) -> str:
    """A distance, or "n/a" when the scenario does not define it (no aircraft of that kind)."""
    return "n/a" if value is None else f"{value:.1f} m"


def print_demo_checks(console: Console, result) -> None:
    """The demo's acceptance checks (a :class:`skytrack.app.demo.DemoResult`) as a PASS/FAIL table."""
    checks, summary = result.checks, result.tracking

    def mark(ok: bool) -> str:
        return "[bold green]PASS[/]" if ok else "[bold red]FAIL[/]"

    table = Table(title="demo summary", show_header=False)
    table.add_row(
        "aircraft in coverage >= 2 min with a confirmed track",
        f"{checks['aircraft_in_coverage_2min_tracked']} / {checks['aircraft_in_coverage_2min']}",
        mark(checks["every_aircraft_in_coverage_2min_tracked"]),
    )
    table.add_row(
        "position RMSE vs one plot's cross-range sigma at mid range",
        f"{_metres(checks['position_rmse_m'])} < {_metres(checks['cross_range_sigma_mid_range_m'])}",
        mark(checks["position_rmse_below_cross_range_sigma"]),
    )
    table.add_row(
        "  RMSE: aircraft with Mode C / primary-only",
        f"{_metres(checks['position_rmse_mode_c_aircraft_m'])} / "
        f"{_metres(checks['position_rmse_primary_only_aircraft_m'])}",
        "",
    )
    # the first run on a machine also compiles the tracker's kernels into numba's cache
    table.add_row("tracking throughput (a first run includes compiling)", f"{summary.plots_per_s:,.0f} plots/s", "")
    table.add_row("report folder", str(result.out), f"{result.elapsed_s:.1f} s")
    console.print(table)

"""Printing of ``skytrack demo``; the pipeline itself is :mod:`skytrack.app.demo`.

With ADS-B in the scenario the demo also prints the identification summary (issue 9, item 7):
the table of :func:`skytrack.cli.identification_view.identification_table` (identified
correctly, late, not identified, wrong labels, time to identify, faulty ADS-B, the problem
aircraft) and the three identification checks in the demo summary.
"""

from __future__ import annotations

from rich.console import Console
from rich.table import Table


def demo_passed(result) -> bool:
    """Whether every pass/fail check of the demo passed (:attr:`skytrack.app.demo.DemoResult.passed`)."""
    return bool(result.passed)


def _metres(value) -> str:
    """A distance, or "n/a" when the scenario does not define it (no aircraft of that kind)."""
    return "n/a" if value is None else f"{value:.1f} m"


def _seconds(value) -> str:
    return "-" if value is None else f"{value:.0f}"


def print_demo_identification(console: Console, result) -> None:
    """The identification report against truth, when the demo's scenario has ADS-B."""
    from skytrack.cli.identification_view import identification_table

    if result.identification is None:
        return
    console.print(identification_table(result.identification))
    console.print(f"identification written to {result.identification_path} and identification_per_aircraft.csv")


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
    if result.identification is not None:
        table.add_row(
            "ADS-B aircraft without fault, tracked >= 60 s, identified correctly",
            f"{checks['sound_identified_correctly']} / {checks['adsb_sound_equipped_tracked_60s']}",
            mark(checks["identification_every_sound_equipped_aircraft_tracked_60s_identified"]),
        )
        table.add_row(
            "track rows with a wrong label (tracks)",
            f"{checks['wrong_label_rows']} ({checks['wrong_label_tracks']})",
            mark(checks["identification_no_wrong_label"]),
        )
        faulty = ", ".join(checks["faulty_adsb_aircraft"]) or "none"
        left = ", ".join(checks["faulty_adsb_aircraft_left_unidentified"]) or "none"
        table.add_row("aircraft with faulty ADS-B: left unidentified", f"{faulty}: {left}",
                      mark(checks["identification_faulty_adsb_aircraft_left_unidentified"]))
        table.add_row("  time to identify: median / max",
                      f"{_seconds(checks['median_time_to_identify_s'])} / {_seconds(checks['max_time_to_identify_s'])} s",
                      "")
        table.add_row("  of them without Mode S (by the sequential test alone): identified, median time",
                      f"{checks['identified_without_mode_s']} / {checks['adsb_sound_tracked_60s_without_mode_s']}, "
                      f"{_seconds(checks['median_time_to_identify_without_mode_s_s'])} s", "")
    # the first run on a machine also compiles the tracker's kernels into numba's cache
    what = "tracking and ADS-B identification" if result.identification is not None else "tracking"
    table.add_row(f"{what} throughput (a first run includes compiling)", f"{summary.plots_per_s:,.0f} plots/s", "")
    table.add_row("report folder", str(result.out), f"{result.elapsed_s:.1f} s")
    console.print(table)

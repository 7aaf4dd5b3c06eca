"""The rich printout of an identification report against truth (issue 9, items 3/4/7: the
identification summary that ``skytrack identify tracks``, ``skytrack track --adsb`` and the demo
print; spec 001 R13).

:func:`identification_table` turns a :class:`skytrack.analysis.identification.IdentificationReport`
into one printable table: the totals (equipped aircraft, tracked long enough, identified
correctly, late, unstable, not identified, wrong labels, time to identify), the acceptance
verdicts of issue 9, the problem cases per aircraft (every aircraft that is not simply
identified, has faulty ADS-B or a wrong label), the wrong labels per track, and the findings
in words.  Only rich is imported: the report is read through its attributes.
"""

from __future__ import annotations

from rich.markup import escape
from rich.table import Table
from rich.text import Text

#: findings printed below the tables (all of them are in the report and its JSON)
MAX_FINDINGS = 15
_STATUS_STYLE = {"identified": "green", "late": "yellow", "unstable": "yellow", "not identified": "red",
                 "not tracked long enough": "dim"}


def _text(value, missing: str = "-") -> str:
    return value if isinstance(value, str) else missing


def _seconds(value) -> str:
    return "-" if value is None or value != value else f"{value:.0f}"


def _totals_table(report) -> Table:
    totals = report.totals
    table = Table(title="identification against truth", title_justify="left")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    tracked = totals["tracked_long_enough"]
    min_s = report.parameters["min_tracked_s"]
    rows = [
        ("ADS-B-equipped aircraft", totals["equipped_aircraft"]),
        (f"tracked >= {min_s:g} s", tracked),
        ("identified correctly, label held", f"{totals['identified']} of {tracked}"),
        ("identified correctly, label held on < "
         f"{100 * report.parameters['hold_fraction']:g} % of later instants", totals["unstable"]),
        ("identified late", totals["late"]),
        ("not identified", totals["not_identified"]),
        (f"tracked < {min_s:g} s", totals["not_tracked_long_enough"]),
        ("faulty ADS-B aircraft (left unidentified)",
         f"{totals['adsb_faulty_aircraft']} ({totals['adsb_faulty_left_unidentified']})"),
        ("wrong-label rows / tracks / aircraft",
         f"{totals['wrong_label_rows']} / {totals['wrong_label_tracks']} / {totals['wrong_label_aircraft']}"),
        ("labelled rows (correct)", f"{totals['labelled_rows']} ({totals['correct_label_rows']})"),
        ("duplicate-track label rows", totals["duplicate_label_rows"]),
        ("median / max time to identify (s)",
         f"{_seconds(totals['median_time_to_identify_s'])} / {_seconds(totals['max_time_to_identify_s'])}"),
    ]
    for name, value in rows:
        table.add_row(escape(name), escape(str(value)))
    return table


def _acceptance_table(report) -> Table:
    table = Table(title="issue 9 acceptance", title_justify="left")
    table.add_column("criterion")
    table.add_column("verdict")
    for name, ok in report.acceptance.items():
        table.add_row(escape(name), "[green]pass[/green]" if ok else "[red]FAIL[/red]")
    return table


def _problem_table(report) -> Table | None:
    frame = report.per_aircraft
    after = f"correct ≥{report.parameters['min_tracked_s']:g} s"
    problems = frame[(frame["status"] != "identified") | frame["adsb_fault"].notna() | (frame["wrong_label_rows"] > 0)]
    if problems.empty:
        return None
    table = Table(title="aircraft to look at", title_justify="left",
                  caption=f"{after}: share of the aircraft's rows from {report.parameters['min_tracked_s']:g} s after "
                          "it was first tracked that carry its address", caption_justify="left")
    for column, justify in (("aircraft", "left"), ("icao24", "left"), ("status", "left"), ("tracked s", "right"),
                            ("to identify s", "right"), (after, "right"), ("wrong rows", "right"),
                            ("ADS-B fault", "left")):
        table.add_column(column, justify=justify, overflow="fold")
    for row in problems.itertuples(index=False):
        fraction = "-" if row.correct_fraction_after != row.correct_fraction_after else f"{row.correct_fraction_after:.0%}"
        fault = "-" if not isinstance(row.adsb_fault, str) else f"{row.adsb_fault} ({_seconds(row.adsb_offset_m)} m" + (
            ", left unidentified)" if row.left_unidentified else ", labelled)")
        style = _STATUS_STYLE.get(row.status, "")
        table.add_row(escape(str(row.target_id)), escape(_text(row.icao24)), Text(row.status, style=style),
                      _seconds(row.tracked_s), _seconds(row.time_to_identify_s), fraction,
                      str(row.wrong_label_rows), escape(fault))
    return table


def _wrong_table(report) -> Table | None:
    frame = report.wrong_labels
    if frame.empty:
        return None
    table = Table(title="wrong labels", title_justify="left")
    for column in ("track", "label", "on aircraft", "address of", "source", "rows", "from s", "to s"):
        table.add_column(column, overflow="fold")
    for row in frame.itertuples(index=False):
        table.add_row(str(row.track_id), escape(str(row.icao24)), escape(_text(row.target_id, "false track")),
                      escape(_text(row.label_owner)), escape(_text(row.identity_source)), str(row.n_rows),
                      _seconds(row.first_s), _seconds(row.last_s))
    return table


def identification_table(report) -> Table:
    """The totals, acceptance verdicts, problem aircraft, wrong labels and findings of an
    :class:`~skytrack.analysis.identification.IdentificationReport`, as one rich table
    (a grid of tables; print it with a rich console)."""
    grid = Table.grid(padding=(1, 0))
    grid.add_column()
    grid.add_row(_totals_table(report))
    grid.add_row(_acceptance_table(report))
    for part in (_problem_table(report), _wrong_table(report)):
        if part is not None:
            grid.add_row(part)
    if report.findings:
        shown = [f"- {line}" for line in report.findings[:MAX_FINDINGS]]
        if len(report.findings) > MAX_FINDINGS:
            shown.append(f"  ... and {len(report.findings) - MAX_FINDINGS} more (report.findings)")
        grid.add_row(Text("\n".join(shown)))
    return grid

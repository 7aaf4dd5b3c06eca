"""Error, warning and report types of ``skytrack.io``.

Every problem found in an input file is located as precisely as the format allows
(DESIGN.md, "Rules that keep it correct"): the file, the 0-based data row, the 1-based
line for CSV files, the column, or a key path for ``sensors.json``.  In strict mode the
first problem raises :class:`InputError`; in lenient mode bad rows are skipped and counted
in a :class:`ReadReport` that the reader returns with the data, so nothing is dropped
silently.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

#: how many example locations a report keeps per reason
MAX_EXAMPLES = 3


def _location_text(file: str | None, row: int | None, line: int | None, column: str | None, where: str | None) -> str:
    parts: list[str] = []
    if file:
        parts.append(file)
    if line is not None and row is not None:
        parts.append(f"line {line} (row {row})")
    elif line is not None:
        parts.append(f"line {line}")
    elif row is not None:
        parts.append(f"row {row}")
    if column:
        parts.append(f"column {column}")
    text = ", ".join(parts)
    if where:
        text = f"{text}: {where}" if text else where
    return text


class InputError(ValueError):
    """A problem in an input file, with its location.

    Attributes: ``file`` (as given by the caller), ``row`` (0-based data row, header
    excluded), ``line`` (1-based line of a CSV file), ``column``, ``where`` (a key path,
    e.g. ``"sensors[1] ('radar2')"``), ``key`` (the JSON key at fault), ``message`` (what
    is wrong) and ``more`` (how many other bad rows the file has).  ``str()`` is one line,
    e.g. ``"plots.csv, line 17 (row 15), column azimuth_deg: value 361.2 is outside [0, 360)"``.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        row: int | None = None,
        line: int | None = None,
        column: str | None = None,
        where: str | None = None,
        key: str | None = None,
        more: int = 0,
    ) -> None:
        self.message = message
        self.file = file
        self.row = row
        self.line = line
        self.column = column
        self.where = where
        self.key = key
        self.more = more
        super().__init__(self.__str__())

    @property
    def location(self) -> str:
        return _location_text(self.file, self.row, self.line, self.column, self.where)

    def __str__(self) -> str:
        location = self.location
        text = f"{location}: {self.message}" if location else self.message
        if self.more:
            plural = "s" if self.more > 1 else ""
            text += f" (and {self.more} more bad row{plural}; lenient mode skips and counts them)"
        return text

    def __reduce__(self):  # keep the keyword-only fields when pickled (multiprocessing)
        return (_rebuild_input_error, (self.message, self.__dict__.copy()))


def _rebuild_input_error(message: str, state: dict) -> InputError:
    state = {k: v for k, v in state.items() if k != "message"}
    return InputError(message, **state)


class InputWarning(UserWarning):
    """Something a reader did to the data that the user should know about (strict mode)."""


@dataclass
class SkippedRows:
    """Rows skipped for one reason: how many, and where the first few are."""

    reason: str
    count: int = 0
    examples: list[InputError] = field(default_factory=list)


@dataclass
class ReadReport:
    """What a lenient read skipped and why, plus warnings about conversions.

    ``rows_read`` counts the data rows found in the file (including malformed CSV lines),
    ``rows_kept`` the rows returned.  ``skipped`` maps a reason (e.g.
    ``"azimuth_deg outside [0, 360)"``) to its count and first example locations; a row
    with several problems counts once under each reason but once in ``rows_skipped``.
    """

    file: str
    rows_read: int = 0
    rows_kept: int = 0
    skipped: dict[str, SkippedRows] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def rows_skipped(self) -> int:
        return self.rows_read - self.rows_kept

    @property
    def ok(self) -> bool:
        """True when nothing was skipped and nothing needs a warning."""
        return not self.skipped and not self.warnings

    def add_skipped(self, reason: str, count: int, examples: list[InputError]) -> None:
        entry = self.skipped.setdefault(reason, SkippedRows(reason))
        entry.count += count
        room = MAX_EXAMPLES - len(entry.examples)
        entry.examples.extend(examples[: max(room, 0)])

    def warn(self, message: str) -> None:
        self.warnings.append(message)

    def __str__(self) -> str:
        lines = [f"{self.file}: {self.rows_read} rows read, {self.rows_kept} kept, {self.rows_skipped} skipped"]
        for entry in self.skipped.values():
            examples = "; ".join(
                f"{_location_text(None, e.row, e.line, None, e.where) or 'file'}: {e.message}" for e in entry.examples
            )
            lines.append(f"  {entry.count} × {entry.reason}" + (f" (e.g. {examples})" if examples else ""))
        lines.extend(f"  warning: {w}" for w in self.warnings)
        return "\n".join(lines)


def refuse_overwriting(out: str | Path, **inputs: str | Path | None) -> None:
    """An :class:`InputError` when the output file ``out`` is one of the ``inputs`` (named by
    their option, e.g. ``plots=...``): writing it would destroy the data being read."""
    target = Path(out).resolve()
    for option, path in inputs.items():
        if path is not None and Path(path).resolve() == target:
            raise InputError(f"the output file is the {option} input: writing it would overwrite the data being read",
                             file=str(out))

"""Text problems of CSV files that pyarrow's reader cannot report: bytes that are not UTF-8.

pyarrow decodes the text of a malformed line before it hands the line to our handler of
invalid rows; when that line also holds bytes that are not UTF-8 the decoding fails inside
pyarrow, which prints "Exception ignored ..." with a traceback and aborts the read.
:func:`undecodable_lines_silenced` keeps that report off the user's terminal and notes it;
:func:`undecodable_error` then finds the line (:func:`first_undecodable_line`), so that the
read ends with one located error instead (lenient mode cannot skip the line: the reader stops
at it).
"""

from __future__ import annotations

import codecs
import contextlib
import gzip
import io
import sys
from collections.abc import Iterator
from pathlib import Path

from skytrack.io.errors import InputError

_BLOCK_BYTES = 1 << 20


def open_text(path: Path) -> io.TextIOBase:
    """A ``.csv`` / ``.csv.gz`` file as text for the readers that only locate lines and fields
    (header, line numbers): bytes that are not UTF-8 become U+FFFD there, since pyarrow reads
    the values and :func:`undecodable_error` reports such a line."""
    if path.name.lower().endswith(".gz"):
        return gzip.open(path, "rt", encoding="utf-8-sig", errors="replace", newline="")
    return open(path, encoding="utf-8-sig", errors="replace", newline="")  # pyarrow skips a BOM too


@contextlib.contextmanager
def undecodable_lines_silenced(caught: list[BaseException]) -> Iterator[None]:
    """Within the block, exceptions that pyarrow could not raise (reported through
    :data:`sys.unraisablehook`) are appended to ``caught`` instead of printed."""
    previous = sys.unraisablehook

    def collect(unraisable) -> None:
        caught.append(unraisable.exc_value)

    sys.unraisablehook = collect
    try:
        yield
    finally:
        sys.unraisablehook = previous


def undecodable_error(path: Path, caught: list[BaseException]) -> InputError | None:
    """The located error of a read that pyarrow aborted on a line that is not UTF-8, if that
    is what happened (``caught`` holds a UnicodeDecodeError and the file has such a line)."""
    if not any(isinstance(exc, UnicodeDecodeError) for exc in caught):
        return None
    bad = first_undecodable_line(path)
    if bad is None:
        return None
    line, byte, value = bad
    return InputError(f"byte {byte} (0x{value:02x}) is not UTF-8 text", file=str(path), line=line)


def first_undecodable_line(path: Path) -> tuple[int, int, int] | None:
    """(1-based line, 1-based byte in that line, the byte) of the first byte sequence that is
    not UTF-8 in a ``.csv`` or ``.csv.gz`` file, or None when the whole text is UTF-8."""
    opener = gzip.open if path.suffix.lower() == ".gz" else open
    decoder = codecs.getincrementaldecoder("utf-8")()
    line, line_start, offset = 1, 0, 0
    with opener(path, "rb") as stream:
        while True:
            block = stream.read(_BLOCK_BYTES)
            try:
                decoder.decode(block, final=not block)
            except UnicodeDecodeError as exc:
                # the decoder keeps an unfinished sequence from the previous block in front
                carried = len(exc.object) - len(block)
                at = max(exc.start - carried, 0)
                before = block[:at]
                line += before.count(b"\n")
                last = before.rfind(b"\n")
                start = offset + last + 1 if last >= 0 else line_start
                return line, offset + at - start + 1, exc.object[exc.start]
            if not block:
                return None
            line += block.count(b"\n")
            last = block.rfind(b"\n")
            if last >= 0:
                line_start = offset + last + 1
            offset += len(block)

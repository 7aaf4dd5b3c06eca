"""Problems found while decoding ASTERIX bytes (issue 11 item 1-2): where they are and why.

A decoder in lenient mode counts every problem in a :class:`DecodeProblems` (kind, byte
offset, block index, detail) and resumes at the next data block; in strict mode the first
problem raises :class:`AsterixDecodeError`, whose message names the byte offset.  Nothing
is dropped silently: the report says how many records and bytes were skipped.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

#: problem kinds, by the code the block scanner (``framing``) emits
BAD_BLOCK_LENGTH = "bad block length"
UNKNOWN_CATEGORY = "unknown category"
TRUNCATED_RECORD = "truncated record"
UNSUPPORTED_ITEM = "unsupported item"
EMPTY_RECORD = "empty record"
#: a record without an item skytrack needs (plots: I048/010, 140, 040; service: I034/010, 000, 030)
REQUIRED_ITEMS = {48: ("010", "140", "040"), 34: ("010", "000", "030")}
MISSING_ITEM = {(cat, item): f"record without I{cat:03d}/{item}" for cat, items in REQUIRED_ITEMS.items()
                for item in items}
NO_POSITION = MISSING_ITEM[48, "040"]
#: a CAT021 record needs one item of each group (I021/010, 080, a time, a position, a height)
CAT021_REQUIRED = (("010",), ("080",), ("071", "073"), ("131", "130"), ("140", "145"))
MISSING_CAT021 = tuple("record without I021/" + " or ".join(group) for group in CAT021_REQUIRED)

PROBLEM_KINDS = {
    1: BAD_BLOCK_LENGTH,
    2: UNKNOWN_CATEGORY,
    3: TRUNCATED_RECORD,
    4: UNSUPPORTED_ITEM,
    5: EMPTY_RECORD,
}


@dataclass(frozen=True)
class AsterixProblem:
    """One problem: ``kind`` (see the module constants), ``offset`` (byte offset in the input
    where the bad block header, record or item starts), ``block`` (0-based data block index),
    ``detail`` (the block length, category, FRN or bytes skipped; see ``text``) and
    ``skipped_bytes`` (bytes not decoded because of it)."""

    kind: str
    offset: int
    block: int
    detail: int
    skipped_bytes: int

    def text(self) -> str:
        what = {
            BAD_BLOCK_LENGTH: f"block length {self.detail}",
            UNKNOWN_CATEGORY: f"category {self.detail}",
            UNSUPPORTED_ITEM: f"FRN {self.detail}",
            TRUNCATED_RECORD: f"record needs more bytes than its block holds (FRN {self.detail})",
            EMPTY_RECORD: "FSPEC without items",
        }.get(self.kind, "record skipped" if self.kind in (*MISSING_ITEM.values(), *MISSING_CAT021) else str(self.detail))
        return f"byte offset {self.offset} (block {self.block}): {self.kind}: {what}; {self.skipped_bytes} bytes skipped"


class AsterixDecodeError(ValueError):
    """Strict decoding met a problem; ``problem`` locates it (``str()`` names the byte offset)."""

    def __init__(self, problem: AsterixProblem) -> None:
        self.problem = problem
        super().__init__(f"ASTERIX input: {problem.text()}")


@dataclass
class DecodeProblems:
    """All problems of one lenient decode, in input order, with ``blocks`` and ``records`` read."""

    problems: list[AsterixProblem] = field(default_factory=list)
    blocks: int = 0
    records: int = 0

    @property
    def count(self) -> int:
        return len(self.problems)

    def counts(self) -> dict[str, int]:
        return dict(Counter(p.kind for p in self.problems))

    @property
    def skipped_bytes(self) -> int:
        return sum(p.skipped_bytes for p in self.problems)

    def summary(self) -> str:
        if not self.problems:
            return f"{self.blocks} blocks, {self.records} records, no problems"
        kinds = ", ".join(f"{n} {k}" for k, n in self.counts().items())
        return (f"{self.blocks} blocks, {self.records} records, {self.count} problems ({kinds}), "
                f"{self.skipped_bytes} bytes skipped; first at {self.problems[0].text()}")

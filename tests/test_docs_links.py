"""The README and docs/ are self-contained: every relative link resolves inside the repository.

Users of the repository do not have the project's internal notes beside it, so no page
may point outside the repository (``../shared`` in particular).  Links are Markdown
inline links and images, ``[text](target)``; links inside fenced code blocks and code
spans are not links and are ignored.  Web links (``http:``, ``https:``, ``mailto:``) and
anchor-only links (``#section``) are not checked; the anchor part of a file link is
dropped before the file is looked up.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")])

_FENCE = re.compile(r"^(```|~~~).*?^\1[^\n]*$", re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1", re.DOTALL)
_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)")
_EXTERNAL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")  # http:, https:, mailto:, ...


def _links(text: str) -> list[str]:
    text = _FENCE.sub("", text)
    text = _CODE_SPAN.sub("", text)
    return _LINK.findall(text)


def _relative_targets(page: Path) -> list[str]:
    return [t for t in _links(page.read_text(encoding="utf-8")) if not _EXTERNAL.match(t) and not t.startswith("#")]


def _name(page: Path) -> str:
    return str(page.relative_to(ROOT))


def test_pages_exist():
    assert (ROOT / "README.md") in PAGES
    assert any(p.parent.name == "methods" for p in PAGES), "docs/methods/ has no page"


def test_link_parser_finds_links_and_skips_code():
    text = (
        "See [formats](docs/formats.md#tracks) and ![fig](img/a.png \"title\").\n"
        "`[not](a-link.md)` and\n```\n[also not](b.md)\n```\n[web](https://example.org) [here](#top)"
    )
    assert _links(text) == ["docs/formats.md#tracks", "img/a.png", "https://example.org", "#top"]


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_relative_links_resolve_inside_the_repository(page: Path):
    broken = []
    for target in _relative_targets(page):
        path = target.split("#", 1)[0].split("?", 1)[0]
        resolved = (page.parent / path).resolve()
        if not resolved.is_relative_to(ROOT):
            broken.append(f"{target} (points outside the repository)")
        elif not resolved.exists():
            broken.append(f"{target} (no such file)")
    assert not broken, f"{_name(page)} has broken links: {broken}"


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_no_page_points_to_shared(page: Path):
    text = page.read_text(encoding="utf-8")
    lines = [i + 1 for i, line in enumerate(text.splitlines()) if "../shared" in line]
    assert not lines, f"{_name(page)} mentions ../shared on line(s) {lines}"

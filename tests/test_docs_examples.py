"""The Python examples of the README and the method pages run as written (docs with runnable examples)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
METHOD_PAGES = sorted((ROOT / "docs" / "methods").glob("*.md"))
METHOD_BLOCKS = [(page.name, block) for page in METHOD_PAGES
                 for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)]


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 1


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_python_example_runs(index, capsys):
    namespace: dict = {}
    exec(compile(BLOCKS[index], f"README.md python block {index}", "exec"), namespace)
    printed = capsys.readouterr().out
    assert printed.strip(), "the example prints its result"
    assert "tracks" in namespace or "tracker" in namespace


@pytest.mark.parametrize("page, block", METHOD_BLOCKS, ids=[f"{p}-{i}" for i, (p, _) in enumerate(METHOD_BLOCKS)])
def test_method_page_python_example_runs(page, block, capsys):
    exec(compile(block, f"docs/methods/{page}", "exec"), {})
    assert capsys.readouterr().out.strip(), f"the example of {page} prints its result"

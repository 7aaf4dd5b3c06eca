"""Architecture rules of the package, checked from the source with ``ast`` (nothing is imported).

The file-level import graph of ``src/skytrack`` is built from every ``import`` statement,
wherever it stands (module level, inside functions, under ``if TYPE_CHECKING``):
``import skytrack.a.b``, ``from skytrack.a import b`` and relative imports are resolved
to the file they load, as Python does: ``from package import name`` is the package's
``__init__.py`` when that binds ``name`` (e.g. a function re-exported under its module's
name), else the sub-module ``name`` when there is one.  Parent packages that Python also
initialises on the way are not edges.  Three rules:

1. no import cycle between files;
2. the layer rule: a module of package P imports only packages of the same or a lower layer,
   in the order of :data:`LAYERS` (sub-packages belong to their top package; the top-level
   ``skytrack/__init__.py`` is exempt, and every module may import it);
3. no source file under ``src/`` is longer than :data:`MAX_LINES` lines.

Every check is parametrised per cycle or per file.  Known failures that belong to work in
progress elsewhere are listed in ``KNOWN_*`` and marked ``xfail(strict=True)``: the case
turns into a failure as soon as the file is fixed, and its entry must then be removed.
"""

from __future__ import annotations

import ast
import sys
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = SRC / "skytrack"
MAX_LINES = 600

#: layers, lowest first; a package may import its own layer and the layers below it
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("geo",),
    ("models",),
    ("filters",),
    ("association",),
    ("tracker",),
    ("identify",),
    ("sim",),
    ("analysis",),
    ("io",),
    ("studies",),
    ("app",),
    ("cli", "service"),
)
LAYER_OF = {package: rank for rank, names in enumerate(LAYERS) for package in names}
#: packages that hold data, not code
DATA_PACKAGES = ("scenarios",)
#: modules directly in skytrack/ other than __init__.py (entry points) sit above every layer
TOP_LAYER = len(LAYERS)

#: known cycles (their files, relative to src/skytrack) left to the work that removes them
KNOWN_CYCLES: dict[frozenset[str], str] = {}
#: known layer violations: file -> reason
KNOWN_LAYER_VIOLATIONS: dict[str, str] = {}
#: known files over MAX_LINES: file -> reason
KNOWN_LONG_FILES: dict[str, str] = {}


# --------------------------------------------------------------------------- the graph


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _source_files() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


FILES = _source_files()
MODULES = {_module_name(p): p for p in FILES}


def _rel(path: Path) -> str:
    return path.relative_to(PACKAGE).as_posix()


def _resolve(module: str) -> Path | None:
    """The file that ``import module`` loads, None outside the package or if it does not exist."""
    return MODULES.get(module)


@lru_cache(maxsize=None)
def _bound_names(init: Path) -> frozenset[str]:
    """Names that a package's ``__init__.py`` binds at module level (definitions, assignments, imports)."""
    names: set[str] = set()
    pending = list(ast.parse(init.read_text(encoding="utf-8")).body)
    while pending:
        node = pending.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(n.id for target in targets for n in ast.walk(target) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.If, ast.Try)):
            pending.extend(node.body + node.orelse + getattr(node, "finalbody", []))
            for handler in getattr(node, "handlers", []):
                pending.extend(handler.body)
    return frozenset(names)


def _from_import(base: str, name: str) -> Path | None:
    """The file ``from base import name`` loads: the package if it binds ``name``, else a sub-module."""
    package = _resolve(base)
    if package is not None and package.name == "__init__.py" and name in _bound_names(package):
        return package
    sub = _resolve(f"{base}.{name}")
    return sub if sub is not None else package


def _imports(path: Path) -> set[Path]:
    """Files of the package imported by ``path`` (every import statement in the file)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[Path] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = _resolve(alias.name)
                if target is None and alias.name.startswith("skytrack."):
                    # ``import skytrack.a.b.name`` of a missing module: point at the nearest package
                    target = _nearest(alias.name)
                if target is not None:
                    found.add(target)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base_parts = package.split(".")
                if node.level > 1:
                    base_parts = base_parts[: len(base_parts) - (node.level - 1)]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            if base != "skytrack" and not base.startswith("skytrack."):
                continue
            for alias in node.names:
                target = _from_import(base, alias.name)
                if target is None:
                    target = _nearest(base)
                if target is not None:
                    found.add(target)
    found.discard(path)
    return found


def _nearest(module: str) -> Path | None:
    parts = module.split(".")
    while parts:
        target = _resolve(".".join(parts))
        if target is not None:
            return target
        parts.pop()
    return None


GRAPH: dict[Path, set[Path]] = {path: _imports(path) for path in FILES}


def _strongly_connected(graph: dict[Path, set[Path]]) -> list[list[Path]]:
    """Tarjan's algorithm (iterative): the components with more than one file, each sorted."""
    index: dict[Path, int] = {}
    low: dict[Path, int] = {}
    on_stack: set[Path] = set()
    stack: list[Path] = []
    components: list[list[Path]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(sorted(component))
    return components


def _cycle_path(component: list[Path]) -> list[str]:
    """One closed import path through a strongly connected component, for the message."""
    members = set(component)
    start = component[0]
    path, seen = [start], {start}
    node = start
    while True:
        nxt = sorted(c for c in GRAPH[node] if c in members)
        if start in nxt and len(path) > 1:
            break
        unseen = [c for c in nxt if c not in seen]
        if not unseen:
            break
        node = unseen[0]
        path.append(node)
        seen.add(node)
    return [_rel(p) for p in path + [start]]


CYCLES = _strongly_connected(GRAPH)


# --------------------------------------------------------------------------- 1. cycles


def _cycle_cases():
    cases = []
    for files, reason in sorted(KNOWN_CYCLES.items(), key=lambda item: sorted(item[0])):
        label = " <-> ".join(sorted(files))
        cases.append(pytest.param(files, id=label, marks=pytest.mark.xfail(strict=True, reason=reason)))
    cases.append(pytest.param(None, id="no-other-cycle"))
    return cases


@pytest.mark.parametrize("known", _cycle_cases())
def test_no_import_cycle_between_files(known):
    components = [frozenset(_rel(p) for p in c) for c in CYCLES]
    if known is not None:
        offending = [c for c in components if known <= c]
        assert not offending, "import cycle: " + " -> ".join(
            _cycle_path(sorted(PACKAGE / f for f in offending[0]))
        )
        return
    unexpected = [c for c in CYCLES if not any(k <= frozenset(_rel(p) for p in c) for k in KNOWN_CYCLES)]
    assert not unexpected, "import cycles between files:\n" + "\n".join(
        "  " + " -> ".join(_cycle_path(c)) for c in unexpected
    )


# --------------------------------------------------------------------------- 2. layers


def _top_package(path: Path) -> str | None:
    parts = path.relative_to(PACKAGE).parts
    return parts[0] if len(parts) > 1 else None


def _layer(path: Path) -> int | None:
    package = _top_package(path)
    if package is None:
        return TOP_LAYER
    return LAYER_OF.get(package)


def _marked(files: list[Path], known: dict[str, str]):
    for path in files:
        rel = _rel(path)
        marks = [pytest.mark.xfail(strict=True, reason=known[rel])] if rel in known else []
        yield pytest.param(path, id=rel, marks=marks)


def _layer_violations(path: Path, targets: set[Path]) -> list[str]:
    """What is wrong with ``path``'s imports under the layer rule (empty when nothing is)."""
    package = _top_package(path)
    if package in DATA_PACKAGES:
        return [f"{_rel(path)}: {package}/ is a data package and holds no code"]
    own = _layer(path)
    if own is None:
        return [f"{_rel(path)}: package {package!r} has no layer; add it to LAYERS (and to docs/design.md)"]
    upward = []
    for target in sorted(targets):
        if target == PACKAGE / "__init__.py":
            continue  # the top-level package is initialised by every import anyway
        layer = _layer(target)
        if layer is None or layer > own:
            upward.append(f"{_rel(path)} ({package or 'skytrack'}) imports {_rel(target)} ({_top_package(target) or 'skytrack'})")
    return upward


@pytest.mark.parametrize("path", list(_marked([p for p in FILES if p != PACKAGE / "__init__.py"], KNOWN_LAYER_VIOLATIONS)))
def test_layer_rule(path):
    problems = _layer_violations(path, GRAPH[path])
    assert not problems, "layer rule (a package imports only its own and lower layers):\n  " + "\n  ".join(problems)


# --------------------------------------------------------------------------- 3. file size


@pytest.mark.parametrize("path", list(_marked(sorted(p for p in SRC.rglob("*.py") if "__pycache__" not in p.parts), KNOWN_LONG_FILES)))
def test_source_file_is_at_most_600_lines(path):
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{path.relative_to(SRC).as_posix()} has {lines} lines (at most {MAX_LINES})"


def test_test_modules_have_unique_basenames():
    # the test folders are not packages: pytest imports each test module by its basename, so two
    # files of one name in two folders stop the whole suite at collection ("import file mismatch")
    seen: dict[str, list[str]] = {}
    for path in sorted((ROOT / "tests").rglob("test_*.py")):
        seen.setdefault(path.name, []).append(path.relative_to(ROOT).as_posix())
    clashes = {name: paths for name, paths in seen.items() if len(paths) > 1}
    assert not clashes, f"test modules sharing a basename: {clashes}"


# --------------------------------------------------------------------------- the checker itself


def test_known_failures_name_existing_files():
    """A KNOWN_* entry whose file was removed or renamed would silently stop being checked."""
    named = [f for files in KNOWN_CYCLES for f in files] + list(KNOWN_LAYER_VIOLATIONS) + list(KNOWN_LONG_FILES)
    missing = sorted(f for f in named if not (PACKAGE / f).is_file())
    assert not missing, f"KNOWN_* entries name files that do not exist (remove them): {missing}"


def test_graph_resolves_absolute_relative_and_function_level_imports(tmp_path, monkeypatch):
    """The resolver on a small fake package: every import form, including one inside a function."""
    root = tmp_path / "src"
    pkg = root / "skytrack"
    for rel, text in {
        "__init__.py": "",
        "core/__init__.py": "from skytrack.core.a import x\nfrom skytrack.core.e import e\n",
        "core/a.py": "x = 1\n",
        "core/b.py": "from . import a\nfrom .a import x\nfrom skytrack.core import e\n",
        "core/e.py": "def e():\n    pass\n",
        "geo/__init__.py": "",
        "geo/c.py": "import skytrack.core.b\n\ndef f():\n    from ..core import a\n    from skytrack.sim import d\n",
        "sim/__init__.py": "",
        "sim/d.py": "from skytrack.geo.c import f\nfrom skytrack import core\n",
    }.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)
    this = sys.modules[__name__]
    monkeypatch.setattr(this, "SRC", root)
    monkeypatch.setattr(this, "PACKAGE", pkg)
    files = sorted(pkg.rglob("*.py"))
    monkeypatch.setattr(this, "MODULES", {_module_name(p): p for p in files})
    graph = {p: _imports(p) for p in files}
    rel = {p.relative_to(pkg).as_posix(): {q.relative_to(pkg).as_posix() for q in t} for p, t in graph.items()}
    assert rel["core/b.py"] == {"core/a.py", "core/__init__.py"}  # ``e`` is the function core/__init__ binds
    assert rel["core/__init__.py"] == {"core/a.py", "core/e.py"}
    assert rel["geo/c.py"] == {"core/b.py", "core/a.py", "sim/d.py"}
    assert rel["sim/d.py"] == {"geo/c.py", "core/__init__.py"}
    cycles = _strongly_connected(graph)
    assert [[p.relative_to(pkg).as_posix() for p in c] for c in cycles] == [["geo/c.py", "sim/d.py"]]
    assert _layer_violations(pkg / "geo/c.py", graph[pkg / "geo/c.py"]) == ["geo/c.py (geo) imports sim/d.py (sim)"]
    assert _layer_violations(pkg / "sim/d.py", graph[pkg / "sim/d.py"]) == []
    assert _layer_violations(pkg / "core/b.py", graph[pkg / "core/b.py"]) == []

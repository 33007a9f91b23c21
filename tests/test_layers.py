"""The import structure of the code: rooms, one-way layers, no circles (issue #16).

Reads every module of ``app/`` and ``solvers/`` with :mod:`ast` (no import is executed) and
collects every import, including the ones inside functions (a lazy import is still a
dependency, and the circles this test replaced were all lazy). Then checks:

- no import circle between modules;
- ``solvers`` never imports ``app``, and never touches ``os.environ`` / ``os.putenv``;
- nothing imports a command-line module (``app.commands.*``; ``app.cli`` finds them by name);
- every module of ``app`` lives in a room, and a room imports only rooms below it (the
  layers in :data:`RANK`); two rooms at one rank never import each other, except the
  error module shared by the API and the web pages (:data:`ALLOWED_ACROSS`).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = {"skisnow.app": REPO / "app", "skisnow.solvers": REPO / "solvers"}

#: layers, lowest first: a room may import rooms of a lower rank and itself only
RANK = {
    "solvers": 0,
    "storage": 1,
    "shared": 2,  # top-level modules of app/ (settings, units, presets, bounds, errors, ...)
    "service": 3,
    "training": 4,
    "jobs": 5,
    "evidence": 5,
    "api": 6,
    "web": 6,
    "commands": 7,
    "entry": 8,  # app.cli (finds the commands by name) and app.main (the ASGI app)
}
#: top-level modules of app/ and their room
TOP_LEVEL = {
    "cli": "entry",
    "main": "entry",
    "settings": "shared",
    "units": "shared",
    "presets": "shared",
    "snow": "shared",
    "bounds": "shared",
    "errors": "shared",
    "path_pool": "shared",
    "plots": "shared",
}
#: (importing room, imported module) allowed across one rank: the web pages answer errors and
#: check callers as the API does (one error module, one access module)
ALLOWED_ACROSS = {
    ("web", "skisnow.app.api.problems"),
    ("web", "skisnow.app.api.access"),
}


def _modules() -> dict[str, Path]:
    out = {}
    for prefix, root in PACKAGES.items():
        for path in sorted(root.rglob("*.py")):
            if "migrations" in path.parts and "versions" in path.parts:
                continue
            rel = path.relative_to(root).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([prefix, *parts])] = path
    return out


MODULES = _modules()


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(module: str, path: Path) -> set[str]:
    """Every skisnow module ``module`` imports (``from pkg import name`` counts ``pkg.name``
    when that is a module, else ``pkg``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, is_package, node)
            names = [
                f"{target}.{a.name}" if f"{target}.{a.name}" in MODULES else target
                for a in node.names
            ]
        else:
            continue
        for name in names:
            while name and name not in MODULES:
                name = name.rpartition(".")[0]
            if name and name != module and name.startswith("skisnow."):
                found.add(name)
    return found


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def room(module: str) -> str:
    if module.startswith("skisnow.solvers"):
        return "solvers"
    parts = module.split(".")
    if len(parts) == 2:  # skisnow.app itself
        return "entry"
    sub = parts[2]
    if (REPO / "app" / sub).is_dir():
        return sub
    return TOP_LEVEL.get(sub, f"<outside the rooms: {sub}>")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_walk_sees_the_code():
    """Guards the checks below against walking nothing."""
    assert "skisnow.solvers.micro" in MODULES and "skisnow.app.cli" in MODULES
    assert len(MODULES) > 40
    assert any("skisnow.solvers.micro" in deps for deps in GRAPH.values())


def test_no_import_circle():
    assert _cycles(GRAPH) == []


def test_cycle_finder_finds_a_planted_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]


def test_solvers_never_import_app():
    bad = {m: sorted(d for d in deps if d.startswith("skisnow.app")) for m, deps in GRAPH.items()}
    assert {m: d for m, d in bad.items() if m.startswith("skisnow.solvers") and d} == {}


def test_solvers_never_write_the_environment():
    offenders = []
    for module, path in MODULES.items():
        if not module.startswith("skisnow.solvers"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr in {"environ", "putenv", "unsetenv"}:
                offenders.append(f"{module}:{node.lineno}")
    assert offenders == []


def test_nothing_imports_a_command_module():
    bad = {
        m: sorted(d for d in deps if d.startswith("skisnow.app.commands."))
        for m, deps in GRAPH.items()
    }
    assert {m: d for m, d in bad.items() if d} == {}


def test_every_module_is_in_a_room():
    assert {m: room(m) for m in MODULES if room(m) not in RANK} == {}


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_go_one_way(module):
    mine = room(module)
    if mine not in RANK:
        pytest.fail(f"{module} is outside the rooms")
    wrong = []
    for dep in sorted(GRAPH[module]):
        theirs = room(dep)
        if theirs == mine or any(
            (mine, prefix) in ALLOWED_ACROSS and dep.startswith(prefix)
            for prefix in [dep.rsplit(".", 1)[0], dep]
        ):
            continue
        if RANK.get(theirs, 99) >= RANK[mine]:
            wrong.append(f"{dep} ({theirs})")
    assert wrong == [], f"{module} ({mine}) imports a room at or above its own"

"""Every doc names the code it describes, and every code path a doc names exists (issue #16:
moves must not leave docs pointing at modules that are gone)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = [*sorted((REPO / "docs").glob("*.md")), REPO / "README.md"]
#: a file path of the code: app/x.py, app/room/x.py, solvers/x.py, scripts/x.py
PATH_RE = re.compile(r"(?<![\w/.-])((?:app|solvers|scripts)/[\w/]+\.py)")
#: a dotted module reference: app.x[.y] or solvers.x (docs write them without ``skisnow.``)
DOTTED_RE = re.compile(r"(?<![\w.])(?:skisnow\.)?((?:app|solvers)(?:\.[a-z_][a-z0-9_]*)+)")


def _resolves(dotted: str) -> bool:
    """``app.x.y`` is a module, or an attribute path under one (``app.service.contact``)."""
    parts = dotted.split(".")
    for n in range(len(parts), 1, -1):
        name = "skisnow." + ".".join(parts[:n])
        try:
            if importlib.util.find_spec(name) is not None:
                return True
        except ModuleNotFoundError:
            continue
    return False


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_doc_names_its_code_and_the_code_exists(doc):
    text = doc.read_text(encoding="utf-8")
    paths = set(PATH_RE.findall(text))
    dotted = {d for d in DOTTED_RE.findall(text) if not d.endswith(("_py",))}
    assert paths or dotted, f"{doc.name} names no module of the code"
    missing = sorted(p for p in paths if not (REPO / p).exists())
    assert missing == [], f"{doc.name} names files that do not exist"
    unresolved = sorted(d for d in dotted if not _resolves(d))
    assert unresolved == [], f"{doc.name} names modules that do not exist"


def test_the_checks_catch_a_stale_name():
    assert not (REPO / "app/bench_accuracy.py").exists()
    assert PATH_RE.findall("see `app/bench_accuracy.py`") == ["app/bench_accuracy.py"]
    assert not _resolves("app.bench_accuracy")
    assert _resolves("app.service.contact") and _resolves("solvers.micro.solve_micro")

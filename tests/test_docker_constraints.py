"""The Docker image's pinned dependencies (issue #27, "left from the last round"): the
constraints file covers the runtime closure of pyproject.toml within its ranges, and the
Dockerfile installs with it."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location(
        "docker_constraints", ROOT / "scripts" / "docker_constraints.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_runtime_dependency_is_pinned_within_its_range():
    dc = _script()
    reqs = dc.top_requirements()
    closure = dc.runtime_closure(reqs)
    pins = dc.read_pins()
    # the closure follows extras and the installed packages' requirements
    assert {"fastapi", "starlette", "uvicorn", "uvloop", "httptools", "distributed"} <= set(closure)
    assert dc.problems(pins, reqs, closure) == []
    assert all(re.fullmatch(r"[0-9][0-9A-Za-z.+!-]*", v) for v in pins.values()), pins


def test_the_check_finds_a_missing_pin_and_one_out_of_range():
    dc = _script()
    reqs = [Requirement("fastapi>=0.110"), Requirement("setuptools>=68")]
    closure = {"fastapi": set(), "starlette": set(), "setuptools": set()}
    found = dc.problems({"fastapi": "0.120.0", "setuptools": "65.5.0"}, reqs, closure)
    assert found == ["starlette is not pinned", "setuptools==65.5.0 is outside pyproject's >=68"]


def test_the_dockerfile_installs_with_the_constraints():
    text = (ROOT / "Dockerfile").read_text()
    assert re.search(r"^COPY scripts/docker-constraints\.txt /constraints\.txt$", text, re.M)
    install = re.search(r"pip install -r /requirements\.txt -c /constraints\.txt", text)
    assert install, "the dependency install of the Dockerfile must use -c /constraints.txt"

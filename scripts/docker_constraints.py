"""Write or check scripts/docker-constraints.txt, the exact versions of the Docker image's
dependencies (Dockerfile: ``pip install -r requirements -c constraints``).

The pins are the runtime closure of pyproject.toml's ``dependencies`` and
``build-system.requires`` (each requirement with its extras, followed through the installed
packages' metadata), at the versions installed in this environment (the venv the test suite
passed in); the build tools the test venv does not hold at a version the build accepts
(``wheel``; ``setuptools`` older than the build's floor) keep the pins of the existing file,
and so do packages outside this environment's closure that a fresh resolve may need
(``tzdata``: python-dateutil 4 requires it, the 2.9 installed here does not).

    python scripts/docker_constraints.py            # rewrite scripts/docker-constraints.txt
    python scripts/docker_constraints.py --check    # exit 1 naming what is missing or off

tests/test_docker_constraints.py checks the file the same way.
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
CONSTRAINTS = ROOT / "scripts" / "docker-constraints.txt"
HEADER = """\
# Exact versions for the Docker image's dependencies (Dockerfile: pip install -c), so that two
# builds of one commit install the same packages: the runtime closure of pyproject.toml's
# dependencies and build requirements, at the versions of the venv the test suite passed in.
# Regenerate with `python scripts/docker_constraints.py`; tests/test_docker_constraints.py
# checks that every package of the closure is pinned here, within pyproject's ranges.
# scripts/docker_ci.sh checks that the image holds exactly these versions.
"""


def top_requirements(pyproject: Path = ROOT / "pyproject.toml") -> list[Requirement]:
    """The image's requirements: ``project.dependencies`` and ``build-system.requires``."""
    p = tomllib.loads(pyproject.read_text())
    return [Requirement(r) for r in p["project"]["dependencies"] + p["build-system"]["requires"]]


def runtime_closure(reqs: list[Requirement]) -> dict[str, set[str]]:
    """Canonical name -> extras asked for, of ``reqs`` and everything they require in this
    environment (markers evaluated here, with the extras asked for). A requirement that is not
    installed is kept (its own requirements are unknown)."""
    seen: dict[str, set[str]] = {}
    stack = list(reqs)
    while stack:
        req = stack.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": ""}):
            continue
        name = canonicalize_name(req.name)
        extras = set(req.extras)
        if name in seen and extras <= seen[name]:
            continue
        seen[name] = seen.get(name, set()) | extras
        try:
            requires = metadata.distribution(req.name).requires or []
        except metadata.PackageNotFoundError:
            continue
        for text in requires:
            sub = Requirement(text)
            wanted = seen[name] | {""}
            if sub.marker is None or any(sub.marker.evaluate({"extra": e}) for e in wanted):
                sub.marker = None
                stack.append(sub)
    return seen


def read_pins(path: Path = CONSTRAINTS) -> dict[str, str]:
    """Canonical name -> pinned version of a constraints file (``name==version`` lines)."""
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[canonicalize_name(name)] = version.strip()
    return pins


def problems(pins: dict[str, str], reqs: list[Requirement], closure: dict) -> list[str]:
    """What is wrong with ``pins``: a package of the closure not pinned, or a top-level
    requirement whose pin is outside its range."""
    out = [f"{n} is not pinned" for n in sorted(closure) if n not in pins]
    for req in reqs:
        pin = pins.get(canonicalize_name(req.name))
        if pin is not None and not req.specifier.contains(Version(pin), prereleases=True):
            out.append(f"{req.name}=={pin} is outside pyproject's {req.specifier}")
    return out


def generate(reqs: list[Requirement], closure: dict, old: dict[str, str]) -> str:
    lines = []
    top = {canonicalize_name(r.name): r for r in reqs}
    for name in sorted(closure):
        try:
            version = metadata.version(name)
        except metadata.PackageNotFoundError:
            version = None
        req = top.get(name)
        if version is None or (req is not None and not req.specifier.contains(Version(version))):
            version = old.get(name)  # a build tool the venv lacks (or has too old)
        if version is None:
            raise SystemExit(f"{name}: not installed here and not pinned in {CONSTRAINTS.name}")
        lines.append(f"{metadata_name(name)}=={version}")
    # pins of the existing file outside this environment's closure are kept: another fresh
    # resolve may need them (python-dateutil 4, which a fresh venv gets, requires tzdata; this
    # venv's 2.9 does not), and a constraint on a package that is not installed does nothing
    lines += [f"{n}=={v}" for n, v in old.items() if n not in closure]
    return (
        HEADER
        + "\n".join(sorted(lines, key=lambda line: canonicalize_name(line.split("==")[0])))
        + "\n"
    )


def metadata_name(name: str) -> str:
    try:
        return metadata.distribution(name).metadata["Name"]
    except metadata.PackageNotFoundError:
        return name


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="check the file, write nothing")
    args = ap.parse_args(argv)
    reqs = top_requirements()
    closure = runtime_closure(reqs)
    if args.check:
        found = problems(read_pins(), reqs, closure)
        print("\n".join(found) or f"{len(closure)} packages pinned", file=sys.stderr)
        return 1 if found else 0
    CONSTRAINTS.write_text(generate(reqs, closure, read_pins()))
    print(f"{CONSTRAINTS}: {len(closure)} packages", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Install anywhere (issue #13): the shipped tables are found after a plain wheel install.

The end-to-end test builds the wheel from a copy of the source, installs it with its
dependencies (from the package index, through the pip cache) into a fresh virtual environment
and runs ``skisnow solve`` and ``skisnow serve`` from a folder outside the clone. It takes one
to three minutes (most of it the dependency install) and needs the package index.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
import urllib.error
import urllib.request
import zipfile
from pathlib import Path

import pytest
from skisnow.app.settings import Settings
from skisnow.app.storage import common
from skisnow.app.storage.tables import read_manifest
from skisnow.solvers.errors import DataFileError

REPO = Path(__file__).resolve().parents[1]

#: what the wheel is built from (as in the Dockerfile): copied, so the build writes no
#: build/ or egg-info into the clone
SOURCE_ITEMS = ["pyproject.toml", "README.md", "app", "solvers", "tables"]

SOLVE_ARGS = (
    "solve --ski ski-a --grind grind-1 --load-kg 40 --load-position-mm -160 "
    "--snow-modulus-mpa 200 --porosity 0.5"
).split()


# ---------------------------------------------------------------------------------------------
# fast checks of the configuration and the lookup order
# ---------------------------------------------------------------------------------------------


def test_every_package_is_listed_in_pyproject():
    """pyproject.toml lists the packages, all under the one import name ``skisnow`` (the
    folders app/, solvers/ and tables/ are mapped to skisnow.app, skisnow.solvers and
    skisnow.tables: generic top-level names such as ``app`` clash with other distributions)."""
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    on_disk = {
        ".".join(("skisnow", *d.relative_to(REPO).parts))
        for top in ("app", "solvers")
        for d in [REPO / top, *(REPO / top).rglob("*")]
        if d.is_dir() and d.name != "__pycache__" and any(d.glob("*.py"))
    }
    assert on_disk - listed == set(), "add these to [tool.setuptools] packages in pyproject.toml"
    assert {p.split(".")[0] for p in listed} == {"skisnow"}
    for folder in ("app", "solvers", "tables"):
        assert config["package-dir"][f"skisnow.{folder}"] == folder
    assert "skisnow.tables" in listed


def test_code_imports_only_the_skisnow_names():
    """No module imports the bare folder names ``app`` or ``solvers``: they resolve in a clone
    (its root is on ``sys.path`` under ``python -m pytest``) but not after an install."""
    import ast

    bare = []
    for top in ("app", "solvers", "scripts", "tests"):
        for path in (REPO / top).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                bare += [
                    f"{path.relative_to(REPO)}:{node.lineno} {n}"
                    for n in names
                    if n.split(".")[0] in ("app", "solvers")
                ]
    assert bare == [], "import skisnow.app / skisnow.solvers instead:\n" + "\n".join(bare)


def test_tables_dir_order(monkeypatch, tmp_path):
    monkeypatch.delenv(common.TABLES_DIR_ENV, raising=False)
    # 2. a source checkout (this clone): its top-level tables/
    assert common.is_source_checkout()
    assert common.tables_dir() == REPO / "tables"
    assert Settings().tables_dir == REPO / "tables"
    # 1. the environment variable wins, for the resolver and the settings alike
    monkeypatch.setenv(common.TABLES_DIR_ENV, str(tmp_path))
    assert common.tables_dir() == tmp_path
    assert Settings().tables_dir == tmp_path
    monkeypatch.delenv(common.TABLES_DIR_ENV)
    # 3. not a checkout (REPO_ROOT is site-packages): the installed package data, a namespace
    # package (a stand-in name here: the clone's editable install maps skisnow.tables itself)
    site = tmp_path / "site-packages"
    (site / "skisnow_install_test" / "tables").mkdir(parents=True)
    (site / "skisnow_install_test" / "tables" / "manifest.json").write_text("{}")
    monkeypatch.setattr(common, "REPO_ROOT", site)
    monkeypatch.setattr(common, "TABLES_PACKAGE", "skisnow_install_test.tables")
    monkeypatch.syspath_prepend(str(site))
    try:
        assert not common.is_source_checkout()
        assert common.tables_dir() == site / "skisnow_install_test" / "tables"
        assert common.docs_dir() == Path.cwd() / "docs"
        assert common.git_commit() == "unknown"
        # neither there: the site-packages path, which the manifest reader then reports
        monkeypatch.setattr(common, "TABLES_PACKAGE", "skisnow_install_test.missing")
        assert common.tables_dir() == site / "tables"
    finally:
        for name in [m for m in sys.modules if m.startswith("skisnow_install_test")]:
            del sys.modules[name]


def test_docs_dir_in_checkout():
    assert common.docs_dir() == REPO / "docs"


def test_missing_manifest_names_the_setting(tmp_path):
    with pytest.raises(DataFileError, match="SKISNOW_TABLES_DIR") as err:
        read_manifest(tmp_path)
    assert str(tmp_path / "manifest.json") in str(err.value)


# ---------------------------------------------------------------------------------------------
# end to end: wheel → fresh venv → skisnow solve / serve outside the clone
# ---------------------------------------------------------------------------------------------


def _run(cmd, *, timeout, what, **kwargs) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(
            [str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, **kwargs
        )
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"{what}: no answer within {timeout} s\n{_tail(exc.stderr)}")
    if proc.returncode != 0:
        pytest.fail(
            f"{what} failed (exit {proc.returncode}): {' '.join(map(str, cmd))}\n"
            f"--- stdout ---\n{_tail(proc.stdout)}\n--- stderr ---\n{_tail(proc.stderr)}"
        )
    return proc


def _tail(text, n: int = 4000) -> str:
    if isinstance(text, bytes):
        text = text.decode(errors="replace")
    return (text or "")[-n:]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def installed():
    """(venv bin folder, clean environment, work folder) of a fresh wheel install."""
    if not (REPO / "pyproject.toml").is_file():
        pytest.skip("not a source checkout")
    # a TemporaryDirectory, not tmp_path: the venv is ~1 GB and pytest keeps old tmp_paths
    with tempfile.TemporaryDirectory(prefix="skisnow-install-", ignore_cleanup_errors=True) as t:
        tmp = Path(t)
        src = tmp / "src"
        src.mkdir()
        ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.part", ".checkpoints")
        for item in SOURCE_ITEMS:
            if (REPO / item).is_dir():
                shutil.copytree(REPO / item, src / item, ignore=ignore)
            else:
                shutil.copy2(REPO / item, src / item)

        wheels = tmp / "wheels"
        pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
        _run([*pip, "wheel", "--no-deps", "-w", wheels, src], timeout=300, what="pip wheel")
        (wheel,) = wheels.glob("skisnow-*.whl")
        with zipfile.ZipFile(wheel) as zf:
            names = set(zf.namelist())
        for needed in [
            "skisnow/app/cli.py",
            "skisnow/app/web/static/web.js",
            "skisnow/app/web/templates/page.html",
            # the catalogue's schema (app/storage/schema.py)
            "skisnow/app/storage/migrations/env.py",
            "skisnow/app/storage/migrations/versions/0001_baseline.py",
            "skisnow/solvers/__init__.py",
            "skisnow/tables/manifest.json",
            "skisnow/tables/grind-1.h5",
            "skisnow/tables/skis/manifest.json",
            "skisnow/tables/skis/ski-a.h5",
        ]:
            assert needed in names, f"{needed} missing from {wheel.name}"
        # one top-level import name: pip would silently overwrite another distribution's
        # `app` or `solvers` (and they ours)
        tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
        assert tops == {"skisnow"}, f"top-level names in the wheel: {sorted(tops)}"

        venv = tmp / "venv"
        _run([sys.executable, "-m", "venv", venv], timeout=120, what="python -m venv")
        bindir = venv / ("Scripts" if os.name == "nt" else "bin")
        python = bindir / "python"
        # dependencies from the package index (the pip cache makes a re-run quicker);
        # --no-compile: byte-compiling ~20k files is a third of the install time
        _run(
            [python, "-m", "pip", "--disable-pip-version-check", "install", "--no-compile", wheel],
            timeout=600,
            what="pip install of the wheel and its dependencies",
        )

        env = {
            k: v
            for k, v in os.environ.items()
            if not k.startswith(("SKISNOW_", "PYTHON", "VIRTUAL_ENV", "CONDA"))
        }
        env.update(
            PATH=f"{bindir}{os.pathsep}{env.get('PATH', '')}",
            VIRTUAL_ENV=str(venv),
            SKISNOW_DATA_DIR=str(tmp / "data"),
            NUMBA_CACHE_DIR=str(tmp / "numba"),
            MPLCONFIGDIR=str(tmp / "mpl"),
            PYTHONDONTWRITEBYTECODE="1",
        )
        work = tmp / "work"  # the current folder: outside the clone
        work.mkdir()
        yield bindir, env, work


def test_wheel_install_resolves_paths(installed):
    bindir, env, work = installed
    probe = (
        "import json, skisnow.app as app, skisnow.tables, skisnow.app.storage.common as c; "
        "print(json.dumps({'app': app.__file__, 'tables': str(c.tables_dir()), "
        "'checkout': c.is_source_checkout(), 'docs': str(c.docs_dir()), "
        "'commit': c.git_commit()}))"
    )
    out = json.loads(
        _run([bindir / "python", "-c", probe], timeout=60, what="import", cwd=work, env=env).stdout
    )
    venv = bindir.parent.resolve()
    # the wheel's code, not the clone's editable install
    assert Path(out["app"]).resolve().is_relative_to(venv), out
    tables = Path(out["tables"]).resolve()
    assert tables.is_relative_to(venv) and tables.parts[-2:] == ("skisnow", "tables"), out
    assert not out["checkout"] and out["commit"] == "unknown", out
    assert Path(out["docs"]) == work / "docs", out  # bench/report never write site-packages


def test_wheel_install_solves(installed):
    bindir, env, work = installed
    proc = _run(
        [bindir / "skisnow", *SOLVE_ARGS, "--json"],
        timeout=300,
        what="skisnow solve",
        cwd=work,
        env=env,
    )
    answer = json.loads(proc.stdout)
    assert answer["inputs"]["ski"] == "ski-a" and answer["inputs"]["grind"] == "grind-1"
    assert answer["metrics"]["total_real_contact_area_mm2"] > 0
    assert not (work / "docs").exists()

    # no tables where SKISNOW_TABLES_DIR points: a one-line error naming the setting
    empty = work / "no-tables"
    empty.mkdir()
    proc = subprocess.run(
        [str(bindir / "skisnow"), *SOLVE_ARGS],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=work,
        env={**env, "SKISNOW_TABLES_DIR": str(empty)},
    )
    assert proc.returncode == 2, proc.stderr
    assert "SKISNOW_TABLES_DIR" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def test_wheel_install_other_commands_find_the_shipped_data(installed):
    """Commands that read a demo ski or a shipped texture by name, outside the clone."""
    bindir, env, work = installed
    macro = ["macro", "--ski", "ski-a", "--load-kg", "40", "--load-position-mm", "-160"]
    proc = _run(
        [bindir / "skisnow", *macro, "--snow-modulus-mpa", "200", "--json"],
        timeout=300,
        what="skisnow macro",
        cwd=work,
        env=env,
    )
    assert json.loads(proc.stdout)["apparent_contact_area_cm2"] > 0


def test_wheel_install_serves(installed):
    bindir, env, work = installed
    port = _free_port()
    log_path = work / "serve.log"
    base = f"http://127.0.0.1:{port}"
    with open(log_path, "w") as log:
        server = subprocess.Popen(
            [str(bindir / "skisnow"), "serve", "--host", "127.0.0.1", "--port", str(port)],
            cwd=work,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + 180
        status = None
        while time.monotonic() < deadline:
            if server.poll() is not None:
                pytest.fail(
                    f"skisnow serve exited ({server.returncode}):\n{_tail(log_path.read_text())}"
                )
            try:
                with urllib.request.urlopen(f"{base}/readyz", timeout=5) as r:
                    status, body = r.status, json.loads(r.read())
                if status == 200:
                    break
            except (urllib.error.URLError, ConnectionError, TimeoutError):
                pass
            time.sleep(0.5)
        if status != 200:
            pytest.fail(f"GET /readyz not 200 within 180 s:\n{_tail(log_path.read_text())}")
        assert "ski-a" in body["skis"] and "grind-1" in body["grinds"], body
        with urllib.request.urlopen(f"{base}/", timeout=10) as r:
            assert r.status == 200 and "skisnow" in r.read().decode()
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=10)

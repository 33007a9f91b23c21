"""``skisnow --help`` imports no command module (issue #28: it took 3–4 s, 8 s on a loaded
machine, importing every solver and matplotlib first), and ``--data-dir`` lets the command line
use the service's uploads."""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from skisnow.app import cli
from skisnow.app.storage.catalogue import CatalogueDB

REPO = Path(__file__).resolve().parents[2]

PROBE = """
import contextlib, io, json, sys
from skisnow.app.cli import main
with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.suppress(SystemExit):
    main({argv!r})
heavy = sorted(m for m in ("numpy", "scipy", "numba", "matplotlib", "fastapi", "sqlalchemy",
               "h5py", "torch") if m in sys.modules)
commands = sorted(m for m in sys.modules if m.startswith("skisnow.app.commands."))
print(json.dumps({{"heavy": heavy, "commands": commands, "help": out.getvalue()}}))
"""


def _probe(argv: list[str]) -> dict:
    code = PROBE.format(argv=argv)
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_top_level_help_imports_no_command_and_no_heavy_library():
    seen = _probe(["--help"])
    assert seen["heavy"] == [] and seen["commands"] == []
    for name in cli.COMMANDS:
        assert name in seen["help"]
    assert "--data-dir" in seen["help"]


def test_a_command_imports_only_its_own_module():
    seen = _probe(["serve", "--help"])
    assert seen["commands"] == ["skisnow.app.commands.serve"]
    assert "--port" in seen["help"]


def test_the_one_line_helps_match_the_modules():
    parser = cli.build_parser()  # every module registers itself
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    registered = {a.dest: a.help for a in sub._choices_actions}
    assert registered == {name: help_text for name, (_, help_text) in cli.COMMANDS.items()}


@pytest.fixture()
def data_dir_with_an_upload(tmp_path) -> Path:
    """A service data folder whose catalogue holds one ready uploaded grind (a copy of the
    shipped grind-1 table under another name, as a finished upload job leaves it)."""
    table = tmp_path / "grinds" / "shop-grind.h5"
    table.parent.mkdir()
    shutil.copyfile(REPO / "tables" / "grind-1.h5", table)
    sha = hashlib.sha256(table.read_bytes()).hexdigest()
    db = CatalogueDB(f"sqlite:///{tmp_path / 'catalogue.db'}")
    try:
        db.add_item(
            "grind",
            "shop-grind",
            state="ready",
            file_path=str(table),
            sha256=sha,
            metadata={"shop_code": "S1"},
        )
    finally:
        db.close()
    return tmp_path


def test_solve_sees_the_services_uploads_with_data_dir(
    data_dir_with_an_upload, monkeypatch, capsys
):
    monkeypatch.setenv("SKISNOW_DATA_DIR", str(data_dir_with_an_upload.parent / "elsewhere"))
    case = ["--ski", "ski-a", "--load-kg", "40", "--load-position-mm", "-160"]
    case += ["--snow-modulus-mpa", "200", "--porosity", "0.5", "--ski-model", "rigid", "--json"]
    # without the folder: unknown, with the known names
    assert cli.main(["solve", "--grind", "shop-grind", *case]) == 2
    assert "shop-grind" in capsys.readouterr().err
    argv = ["--data-dir", str(data_dir_with_an_upload), "solve", "--grind", "shop-grind", *case]
    assert cli.main(argv) == 0
    uploaded = json.loads(capsys.readouterr().out)
    assert cli.main(["solve", "--grind", "grind-1", *case]) == 0
    shipped = json.loads(capsys.readouterr().out)
    assert uploaded["inputs"]["grind"] == "shop-grind"
    assert uploaded["metrics"] == shipped["metrics"]  # the same table under another name

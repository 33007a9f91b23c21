"""torch stays out of the service's runtime path: only fitting a camber network imports it.

Each probe runs in a fresh interpreter (this test process may have imported torch already) and
lists the heavy modules that an import pulled in.
"""

import json
import subprocess
import sys

import pytest

PROBE = """
import importlib, json, sys
for name in {modules!r}:
    importlib.import_module(name)
{after}
print(json.dumps(sorted(m for m in ("torch",) if m in sys.modules)))
"""


def _loaded_after(modules: list[str], after: str = "") -> list[str]:
    code = PROBE.format(modules=modules, after=after)
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_service_and_command_line_do_not_import_torch():
    """The ASGI app (API, web pages, jobs, uploads), the whole ``skisnow`` parser and every
    module of the training room import without torch; torch comes only when a fit starts."""
    modules = [
        "skisnow.app.main",
        "skisnow.app.training",
        "skisnow.app.training.data",
        "skisnow.app.training.check",
        "skisnow.app.training.files",
        "skisnow.app.training.model",
        "skisnow.app.training.fit",
        "skisnow.app.commands.train_camber",
    ]
    assert _loaded_after(modules, "from skisnow.app import cli; cli.build_parser()") == []


def test_the_probe_sees_torch():
    """The probe can fail: asking the training room for torch loads it."""
    pytest.importorskip("torch", reason="torch is a test dependency (skisnow[test])")
    after = "from skisnow.app.training.model import import_torch; import_torch()"
    assert _loaded_after(["skisnow.app.training.model"], after) == ["torch"]

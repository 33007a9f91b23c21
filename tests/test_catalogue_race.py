"""Several service processes starting at once on an empty catalogue (every first ``docker run``
with two uvicorn workers) must all come up: issue #15, "startup race"."""

from __future__ import annotations

import multiprocessing as mp

import pytest

PROCESSES = 6
ROUNDS = 8  # before the fix, 9 of 15 rounds had a process fail with "table items already exists"


def _open(url: str, barrier, queue) -> None:
    from app.storage.catalogue import CatalogueDB

    barrier.wait()
    try:
        CatalogueDB(url).close()
        queue.put("ok")
    except Exception as exc:  # reported to the parent, which fails the test with it
        queue.put(f"{type(exc).__name__}: {exc}"[:300])


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="needs fork")
def test_processes_creating_the_catalogue_at_once_all_succeed(tmp_path):
    # imported before the fork, so that the children race on the schema, not on imports
    import app.storage.catalogue  # noqa: F401

    ctx = mp.get_context("fork")
    for r in range(ROUNDS):
        url = f"sqlite:///{tmp_path / f'round{r}' / 'catalogue.db'}"
        barrier, queue = ctx.Barrier(PROCESSES), ctx.Queue()
        procs = [ctx.Process(target=_open, args=(url, barrier, queue)) for _ in range(PROCESSES)]
        for p in procs:
            p.start()
        for p in procs:
            p.join(timeout=60)
        results = [queue.get(timeout=10) for _ in procs]
        assert results == ["ok"] * PROCESSES, (r, [x for x in results if x != "ok"])


def test_serve_refuses_an_unwritable_data_dir_naming_the_setting(tmp_path, monkeypatch, capsys):
    """A data folder the service cannot write (a bind mount owned by another uid in Docker)
    stops ``skisnow serve`` before it binds, with exit code 2 and the setting named (it used to
    exit 0 from inside a worker with ``unable to open database file``)."""
    from app.cli import main

    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("SKISNOW_DATA_DIR", str(blocker / "data"))  # cannot be created
    assert main(["serve", "--port", "1"]) == 2
    err = capsys.readouterr().err
    assert "SKISNOW_DATA_DIR" in err and "not writable" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("host", "tokens", "warned"),
    [
        ("127.0.0.1", {}, False),
        ("::1", {}, False),
        ("localhost", {}, False),
        ("0.0.0.0", {}, True),
        ("192.168.1.5", {}, True),
        ("0.0.0.0", {"secret": "team-a"}, False),
    ],
)
def test_open_writes_on_a_public_address_are_warned_at_start_up(host, tokens, warned):
    from app.commands.serve import open_writes_warning

    text = open_writes_warning(host, tokens)
    assert (text is not None) == warned
    if warned:
        assert host in text and "SKISNOW_TEAM_TOKENS" in text

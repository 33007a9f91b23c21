"""Helpers shared by every writer: atomic replacement, checksums, provenance."""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import os
import shlex
import subprocess
import sys
import tempfile
import tokenize
from collections.abc import Iterator
from pathlib import Path

from skisnow.solvers import __version__
from skisnow.solvers.errors import DataFileError

__all__ = [
    "NPY_READ_ERRORS",
    "TABLES_DIR_ENV",
    "atomic_path",
    "code_version",
    "docs_dir",
    "git_commit",
    "is_source_checkout",
    "provenance",
    "sha256_file",
    "tables_dir",
]

#: the folder above ``app/``: the clone in a source checkout or editable install, the
#: ``site-packages`` folder in a wheel install (then it has no ``pyproject.toml``)
REPO_ROOT = Path(__file__).resolve().parents[2]

#: environment variable that overrides where the texture tables and demo skis are read from
TABLES_DIR_ENV = "SKISNOW_TABLES_DIR"

#: what numpy raises on a damaged ``.npy`` (header or body): besides ValueError, OSError and
#: EOFError, its header parser (tokenize + ``ast.literal_eval``) raises ``SyntaxError`` (e.g. a
#: NUL byte) and ``tokenize.TokenError`` (an unclosed bracket) on a damaged header dict
NPY_READ_ERRORS = (ValueError, OSError, EOFError, SyntaxError, tokenize.TokenError)

#: import name of the shipped ``tables/`` folder inside the wheel (pyproject.toml package-dir)
TABLES_PACKAGE = "skisnow.tables"


def is_source_checkout() -> bool:
    """Whether the code runs from the clone (source tree or editable install), not a wheel."""
    return (REPO_ROOT / "pyproject.toml").is_file()


def _packaged_tables_dir() -> Path | None:
    """The ``tables/`` folder installed as package data ``skisnow.tables`` (None if absent)."""
    import importlib.util

    try:
        spec = importlib.util.find_spec(TABLES_PACKAGE)
    except (ImportError, ValueError):
        return None
    # a namespace package (no __init__.py): its folders, first on sys.path first
    for location in (spec.submodule_search_locations or []) if spec else []:
        if (Path(location) / "manifest.json").is_file():
            return Path(location)
    return None


def tables_dir() -> Path:
    """Folder of the texture tables (``manifest.json``, ``*.h5``) and demo skis (``skis/``).

    Looked up in this order:

    1. ``$SKISNOW_TABLES_DIR`` when set (the Docker image, a shared table folder);
    2. the clone's top-level ``tables/`` when running from a source checkout or editable
       install (``REPO_ROOT/pyproject.toml`` exists);
    3. the copy installed with the package (``skisnow/tables`` in ``site-packages``: wheel,
       ``pip install .``, pipx).

    Never raises: a folder without ``manifest.json`` is reported by the reader
    (:func:`app.storage.tables.read_manifest`), which names ``SKISNOW_TABLES_DIR``.
    """
    env = os.environ.get(TABLES_DIR_ENV)
    if env:
        return Path(env).expanduser()
    checkout = REPO_ROOT / "tables"
    if is_source_checkout() and checkout.is_dir():
        return checkout
    return _packaged_tables_dir() or checkout


def docs_dir() -> Path:
    """Where ``skisnow bench`` and ``skisnow report`` write: the clone's ``docs/`` in a source
    checkout, else ``./docs`` in the current directory (never into ``site-packages``)."""
    return REPO_ROOT / "docs" if is_source_checkout() else Path.cwd() / "docs"


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def git_commit() -> str:
    """Commit of the source tree ("unknown" outside a git checkout; "+dirty" if modified).

    An installed wheel is "unknown" too: its ``site-packages`` may sit inside someone else's
    git repository (a project's ``.venv``), whose commit is not ours.
    """
    if not is_source_checkout():
        return "unknown"
    try:
        out = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        return out + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def code_version() -> str:
    """skisnow version string."""
    return __version__


def provenance(parameters: dict | None = None) -> dict[str, str]:
    """Attributes every written file carries: code version, commit, command line, time."""
    attrs = {
        "code_version": code_version(),
        "git_commit": git_commit(),
        "command_line": shlex.join(sys.argv),
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
    }
    if parameters:
        import json

        attrs["parameters_json"] = json.dumps(parameters, sort_keys=True, default=str)
    return attrs


def _process_umask() -> int:
    # read once at import (os.umask can only be read by setting it; doing that later, in a
    # threaded server, could race with another thread creating a file)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: permissions a plain ``open(path, "w")`` would give a new file (mkstemp gives 0600)
_FILE_MODE = 0o666 & ~_process_umask()


@contextlib.contextmanager
def atomic_path(final: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``final``; rename it onto ``final`` only on success.

    The final file gets the permissions of a normally created file (``0666 & ~umask``), not
    the owner-only 0600 of the temporary file, so a service running as another user can read
    tables and skis that a build wrote.
    """
    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".part", dir=final.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp_path, _FILE_MODE)
        os.replace(tmp_path, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def _json_default(value):
    """JSON for what ``json`` does not know: numpy scalars and arrays as numbers and lists,
    anything else (a path) as its text."""
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


def write_study_json(
    path: str | os.PathLike, schema: str, parameters: dict, body: dict, *, indent: int | None = 1
) -> None:
    """Write a study's results ``{"schema", "provenance", **body}`` atomically to ``path``,
    the provenance (:func:`provenance`) recording ``parameters``; ``indent`` None: compact."""
    doc = {"schema": schema, "provenance": provenance(parameters), **body}
    separators = (",", ":") if indent is None else None
    text = json.dumps(doc, indent=indent, separators=separators, default=_json_default)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def read_json_manifest(
    path: str | os.PathLike, schema: str, what: str = "manifest", hint: str = ""
) -> dict:
    """Read a JSON manifest ``{"schema": schema, "files": {...}}``.

    ``hint`` is appended to the message when the file does not exist (what to set instead).

    Raises
    ------
    DataFileError
        Missing, unreadable, another schema, or no ``files`` mapping; the message names the file.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise DataFileError(f"{what} not found: {path}{hint}") from exc
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{path}: unreadable {what} ({exc})") from exc
    if not isinstance(data, dict) or data.get("schema") != schema:
        raise DataFileError(f"{path}: unsupported {what} schema, expected {schema!r}")
    if not isinstance(data.get("files"), dict):
        raise DataFileError(f"{path}: {what} has no 'files' mapping")
    return data


def check_data_dir(data_dir: Path) -> None:
    """Refuse to start, naming the setting and the user, when the data directory (uploads, the
    SQLite catalogue) cannot be created or written, e.g. a bind mount owned by another uid."""
    try:
        data_dir.mkdir(parents=True, exist_ok=True)
        probe = data_dir / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        uid = os.getuid() if hasattr(os, "getuid") else "?"
        raise DataFileError(
            f"the data directory {data_dir} is not writable by this process (uid {uid}): "
            f"{exc.strerror or exc}. Set SKISNOW_DATA_DIR to a writable folder, or give the "
            "folder to this user (Docker: the image runs as uid 10001; chown the mounted folder "
            "or use a named volume)"
        ) from None

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
from collections.abc import Iterator
from pathlib import Path

from solvers import __version__

__all__ = ["atomic_path", "code_version", "git_commit", "provenance", "sha256_file"]

REPO_ROOT = Path(__file__).resolve().parents[2]


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def git_commit() -> str:
    """Commit of the source tree ("unknown" outside a git checkout; "+dirty" if modified)."""
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


def read_json_manifest(path: str | os.PathLike, schema: str, what: str = "manifest") -> dict:
    """Read a JSON manifest ``{"schema": schema, "files": {...}}``.

    Raises
    ------
    DataFileError
        Missing, unreadable, another schema, or no ``files`` mapping; the message names the file.
    """
    from solvers.errors import DataFileError

    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise DataFileError(f"{what} not found: {path}") from exc
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{path}: unreadable {what} ({exc})") from exc
    if not isinstance(data, dict) or data.get("schema") != schema:
        raise DataFileError(f"{path}: unsupported {what} schema, expected {schema!r}")
    if not isinstance(data.get("files"), dict):
        raise DataFileError(f"{path}: {what} has no 'files' mapping")
    return data

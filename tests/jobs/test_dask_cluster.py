"""Table builds on a real Dask cluster (issue #15 point 2): ``dask scheduler`` and two
``dask worker`` processes on loopback, ``skisnow build-tables --scheduler tcp://…``, one worker
killed (SIGKILL) in the middle of the build. The table must come out with the same data sha256
as a LocalCluster build: Dask reruns the lost worker's chunks on the other one."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.storage.textures import write_texture
from skisnow.solvers.texture import Texture, self_affine_surface

PIXEL_M = 1e-6
POINTS, CHUNK = 16, 1
ARGS = ["--points", str(POINTS), "--chunk-size", str(CHUNK), "--ratio-min", "1e-5"]
ARGS += ["--ratio-max", "0.05"]
WORKER_ARGS = ["--nthreads", "1", "--nworkers", "1", "--no-dashboard", "--death-timeout", "60"]
SKISNOW = [sys.executable, "-m", "skisnow.app.cli"]
DASK = shutil.which("dask") or str(Path(sys.executable).with_name("dask"))


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _spawn(cmd: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen(
        cmd, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True
    )


def _kill(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)


def _data_sha(path: Path) -> str:
    with h5py.File(path, "r") as f:
        return str(f.attrs["data_sha256"])


@pytest.mark.skipif(not Path(DASK).exists(), reason="the dask command is not installed")
def test_build_survives_a_killed_worker_and_matches_a_local_cluster(tmp_path):
    rng = np.random.default_rng(7)
    h = self_affine_surface((128, 128), PIXEL_M, hurst=0.8, rms_height_m=1e-6, rng=rng)
    texture = Texture(h, PIXEL_M, "cluster-tex", source="synthetic seed 7")
    tex_file = tmp_path / "cluster-tex.h5"
    write_texture(texture, tex_file, periodic=True)

    port = _port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    procs: list[subprocess.Popen] = []
    try:
        sched = _spawn(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            tmp_path / "scheduler.log",
        )
        procs.append(sched)
        workers = [
            _spawn(
                [DASK, "worker", address, *WORKER_ARGS, "--name", f"w{i}"],
                tmp_path / f"worker{i}.log",
            )
            for i in range(2)
        ]
        procs += workers
        out = tmp_path / "cluster"
        build = subprocess.Popen(
            [
                *SKISNOW,
                "build-tables",
                str(tex_file),
                "--out",
                str(out),
                "--scheduler",
                address,
                *ARGS,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        # kill one worker once a few chunks are checkpointed, with most of the build to go
        deadline = time.monotonic() + 240
        killed_after = None
        while time.monotonic() < deadline and build.poll() is None:
            done = list(out.glob(".checkpoints/**/*.h5")) if out.exists() else []
            if len(done) >= 2:
                killed_after = len(done)
                _kill(workers[0])
                break
            time.sleep(0.05)
        log, _ = build.communicate(timeout=600)
        assert build.returncode == 0, log
        assert killed_after is not None and killed_after < POINTS // CHUNK, (
            "the worker was not killed in the middle of the build",
            killed_after,
            log,
        )
        assert workers[0].returncode == -signal.SIGKILL
    finally:
        for p in procs:
            _kill(p)

    local = build_tables(
        [texture],
        tmp_path / "local",
        BuildSettings(points=POINTS, ratio_min=1e-5, ratio_max=0.05, chunk_size=CHUNK),
        workers=1,
        processes=False,
        progress=False,
    )
    assert _data_sha(out / "cluster-tex.h5") == _data_sha(local["cluster-tex"])

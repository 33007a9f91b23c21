"""Service settings: one typed object, read once (environment variables ``SKISNOW_*``)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict
from skisnow.app.storage.common import tables_dir as default_tables_dir

#: memory of one serving worker [MB]: one worker held 640 MB at rest and 692 MB at most under
#: 32 clients; two workers held 750–890 MB each after an 8-client run (docs/deployment.md)
WORKER_MEMORY_MB = 900
#: most worker processes chosen by default (each answer runs on one core: app.service.gate)
WORKERS_MAX = 8


def _available_memory_mb() -> float | None:
    """MemAvailable of /proc/meminfo [MB], or None where there is none (not Linux)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def default_workers(cores: int | None = None, available_mb: float | None = None) -> int:
    """The default number of serving workers: one per usable core (each computes one answer
    at a time, app.service.gate), at most :data:`WORKERS_MAX`, and at most one per
    :data:`WORKER_MEMORY_MB` of half the available memory; at least 1.

    On the 2-core benchmark machine that is 2: 8 clients got 80 answers/s (p99 181 ms) with
    two workers and 52/s (p99 174 ms) with one (docs/benchmarks.md, issue #29)."""
    if cores is None:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    if available_mb is None:
        available_mb = _available_memory_mb()
    n = min(int(cores or 1), WORKERS_MAX)
    if available_mb is not None:
        n = min(n, int(0.5 * available_mb // WORKER_MEMORY_MB))
    return max(n, 1)


class Settings(BaseSettings):
    """Settings of ``skisnow serve``; each can be set as ``SKISNOW_<NAME>``."""

    model_config = SettingsConfigDict(env_prefix="SKISNOW_", extra="ignore")

    host: str = Field("127.0.0.1", description="interface to listen on")
    port: int = Field(8000, ge=1, le=65535, description="TCP port")
    workers: int | None = Field(
        None,
        ge=1,
        le=64,
        description="uvicorn worker processes (default: one per usable core, at most "
        "WORKERS_MAX and at most one per WORKER_MEMORY_MB of half the available memory; "
        "default_workers)",
    )
    threads_per_worker: int = Field(1, ge=1, le=64, description="FFT/numba threads per worker")
    tables_dir: Path = Field(
        default_factory=default_tables_dir,
        description="texture tables and ski files (default: the clone's tables/ in a source "
        "checkout, else the copy installed with the package; app.storage.common.tables_dir)",
    )
    max_body_bytes: int = Field(64 * 1024, ge=1024, description="largest accepted request body")
    max_compare_cells: int = Field(16, ge=1, le=256, description="largest ski × grind matrix")
    warm_up: bool = Field(
        True, description="solve one case at start-up so the first request is not slow"
    )

    # ---- catalogue of uploaded skis and grinds, background jobs (docs/uploads.md) ----
    data_dir: Path = Field(
        default_factory=lambda: (
            Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share") / "skisnow"
        ),
        description="writable directory of the catalogue database and uploaded items",
    )
    database_url: str | None = Field(
        None,
        description="SQLAlchemy URL of the catalogue (default sqlite:///DATA_DIR/catalogue.db)",
    )
    max_upload_bytes: int = Field(
        80 * 1024 * 1024,
        ge=1024,
        description="largest accepted upload body (POST skis/grinds); 80 MiB holds a "
        "2048 x 2048 float64 .npy",
    )
    max_grid_points: int = Field(
        4096 * 4096,
        ge=64,
        description="largest uploaded height map (points); larger than max_solve_grid_points: "
        "a map too large for the solver is reduced (POST /v1/grinds reduce)",
    )
    min_grid_side: int = Field(16, ge=2, description="smallest side of an uploaded height map")
    max_camber_cases: int = Field(
        2000,
        ge=1,
        description="most load cases (side, load, load position) of an uploaded camber CSV; "
        "reading stops at the first case beyond it",
    )
    max_camber_rows: int = Field(
        600_000,
        ge=2,
        description="most data rows of an uploaded camber CSV; reading stops at the first row "
        "beyond it",
    )
    max_check_s: float = Field(
        30.0,
        gt=0,
        description="longest synchronous check of an upload (camber CSV rows, a grind's height "
        "map), run in a worker thread; beyond it the upload is refused with 422 [s]",
    )
    table_points: int = Field(48, ge=2, le=512, description="pressure grid points of a table")
    table_chunk_size: int = Field(4, ge=1, description="grid points per table-build task")
    table_workers: int = Field(1, ge=1, le=64, description="Dask workers of a table build")
    table_processes: bool = Field(True, description="Dask workers as processes (else threads)")
    idle_trim_s: float = Field(
        10.0,
        ge=0,
        description="after this long [s] without a request a worker gives freed memory back to "
        "the system (gc and malloc_trim, app/api/idle.py); 0: never",
    )
    ski_cache_mb: float = Field(
        512,
        gt=0,
        le=65536,
        description="memory budget [MB] of the per-ski caches of one worker (profile models, the "
        "band's plausible beams, flex draws, page figures; app/storage/memory.py): least "
        "recently used entries beyond it are dropped and rebuilt on use",
    )
    table_device: Literal["cpu", "cuda", "torch-cpu"] = Field(
        "cpu",
        description="where an uploaded grind's table is solved: cpu (numpy/pyFFTW), cuda (the "
        "torch backend on a GPU, one per Dask worker; docs/deployment.md) or torch-cpu",
    )
    dask_scheduler: str | None = Field(None, description="existing Dask scheduler for builds")
    train_epochs: int = Field(4000, ge=1, description="max Adam epochs of a ski's network")
    train_lbfgs_epochs: int = Field(1500, ge=0, description="max L-BFGS iterations")
    train_ensemble: int = Field(3, ge=1, le=16, description="members of a ski's network")
    ski_max_test_rmse_um: float = Field(
        8.0,
        gt=0,
        description="accuracy check: RMSE where H* < 0.2 mm on held-out measured load cases "
        "(device noise included) [µm]",
    )
    job_workers: int = Field(
        1,
        ge=0,
        le=16,
        description="jobs run at once per service process; 0: none, the jobs run in separate "
        "`skisnow worker` processes on the same database (app/commands/worker.py)",
    )
    job_poll_s: float = Field(1.0, gt=0, description="job runner poll interval [s]")
    job_stale_s: float = Field(
        120.0, gt=0, description="a running job without heartbeat this long is taken over [s]"
    )
    team_tokens: dict[str, str] = Field(
        default_factory=dict,
        description="bearer token -> team; empty (default): no authentication, and changes "
        "must come from the service's own origin (app/api/access.py)",
    )
    trusted_origins: list[str] = Field(
        default_factory=list,
        description="other origins (scheme://host[:port]) whose pages may change the catalogue "
        "when team_tokens is empty, e.g. a proxy's public address that rewrites Host",
    )
    allowed_hosts: list[str] = Field(
        default_factory=list,
        description="host names (or addresses) besides loopback, the listening host and the "
        "trusted origins' hosts that requests may name in their Host header; others are "
        "refused with 421 before routing (DNS rebinding, app/api/access.py). '*': any host "
        '(a proxy in front checks it). JSON list, e.g. \'["skis.example", "10.0.0.5"]\'',
    )
    max_jobs_per_team: int = Field(
        4,
        ge=1,
        description="queued + running jobs of one team (no team tokens: of everyone); "
        "an upload beyond it is 429",
    )
    max_queued_jobs: int = Field(
        16, ge=1, description="queued + running jobs of all teams; an upload beyond it is 429"
    )
    max_solve_grid_points: int = Field(
        1024 * 1024,
        ge=64,
        description="largest grid a grind's table is solved on, after periodisation (mirror "
        "doubles each side: 4x the uploaded points) [points]",
    )

    @property
    def catalogue_url(self) -> str:
        """The catalogue database URL (``database_url`` or SQLite under ``data_dir``)."""
        return self.database_url or f"sqlite:///{Path(self.data_dir) / 'catalogue.db'}"

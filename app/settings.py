"""Service settings: one typed object, read once (environment variables ``SKISNOW_*``)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.storage.common import REPO_ROOT


class Settings(BaseSettings):
    """Settings of ``skisnow serve``; each can be set as ``SKISNOW_<NAME>``."""

    model_config = SettingsConfigDict(env_prefix="SKISNOW_", extra="ignore")

    host: str = Field("127.0.0.1", description="interface to listen on")
    port: int = Field(8000, ge=1, le=65535, description="TCP port")
    workers: int = Field(1, ge=1, le=64, description="uvicorn worker processes")
    threads_per_worker: int = Field(1, ge=1, le=64, description="FFT/numba threads per worker")
    tables_dir: Path = Field(REPO_ROOT / "tables", description="texture tables and ski files")
    max_body_bytes: int = Field(64 * 1024, ge=1024, description="largest accepted request body")
    max_compare_cells: int = Field(16, ge=1, le=256, description="largest ski × grind matrix")
    max_load_kg: float = Field(150.0, gt=0, description="largest equivalent load [kg]")
    warm_up: bool = Field(
        True, description="solve one case at start-up so the first request is not slow"
    )

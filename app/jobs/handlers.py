"""The catalogue's job kinds and their clean-up, for every process that runs jobs: the service
(:mod:`app.api`, ``job_workers`` ≥ 1) and ``skisnow worker`` (:mod:`app.commands.worker`).
"""

from __future__ import annotations

from collections.abc import Callable

from skisnow.app import uploads
from skisnow.app.jobs.runner import FailureHook, Handler, JobContext
from skisnow.app.settings import Settings

__all__ = ["job_handlers"]


def job_handlers(
    settings: Settings, layout: uploads.Layout, on_ready: Callable
) -> tuple[dict[str, Handler], FailureHook]:
    """Handlers per job kind (``uploads.GRIND_JOB``, ``uploads.SKI_JOB``) and the failure hook.

    ``on_ready(item)`` is called with each finished item row: the service loads it into the
    catalogue it serves; a worker process, which serves nothing, passes a no-op (the service
    processes find the item in the database).
    """

    def grind(ctx: JobContext) -> str:
        return uploads.run_grind_job(ctx, layout, settings, on_ready)

    def ski(ctx: JobContext) -> str:
        return uploads.run_ski_job(ctx, layout, settings, on_ready)

    def on_failure(ctx: JobContext, exc: BaseException) -> None:
        uploads.on_job_failure(ctx, layout)

    return {uploads.GRIND_JOB: grind, uploads.SKI_JOB: ski}, on_failure

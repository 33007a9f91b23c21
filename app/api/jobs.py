"""Job routes: the background jobs of uploads (table builds, ski identification/training).

Another team's job is 404 (:mod:`app.api.access`); see docs/uploads.md.
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from skisnow.app.api import catalogue as C
from skisnow.app.api import problems
from skisnow.app.api.responses import JobList, JobView

router = APIRouter(tags=["catalogue"])


@router.get(
    "/v1/jobs/{job_id}", response_model=JobView, responses=problems.responses(401, 404, 422)
)
def get_job(request: Request, job_id: str, who: C.Reader) -> dict:
    """A background job: state (queued, running, done, failed), progress 0..1, errors
    (another team's job is 404)."""
    state = C.catalogue_state(request)
    job = state.db.job(job_id)
    item = state.db.item(job.item_id) if job is not None and job.item_id else None
    if job is None or (item is not None and not who.sees(item.team, item.read_only)):
        return problems.problem(404, "Unknown job", f"no job {job_id!r}")
    return C.job_view(state.db, job)


@router.get("/v1/jobs", response_model=JobList, responses=problems.responses(401))
def list_jobs(request: Request, who: C.Reader) -> dict:
    """The 100 most recent jobs (with team tokens: those the caller's team may see)."""
    state = C.catalogue_state(request)
    jobs = state.db.jobs(by_team=who.teams_on, team=who.team)
    return {"jobs": [C.job_view(state.db, j) for j in jobs]}

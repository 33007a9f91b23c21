"""Routes of one catalogue item, the same for skis and grinds: show, rename, delete.

:func:`item_routes` adds them to the router of :mod:`app.api.skis` or :mod:`app.api.grinds`.
Shipped items are read-only (403); with team tokens another team's items are 404.
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response
from skisnow.app.api import catalogue as C
from skisnow.app.api import problems
from skisnow.app.api.models import RenameBody
from skisnow.app.api.responses import ItemDetail, ItemView
from skisnow.app.jobs import uploads
from skisnow.app.service import beam_report, profile_report

__all__ = ["item_routes"]


def item_routes(router: APIRouter, kind: str, plural: str) -> None:
    """Add ``GET``, ``PATCH`` and ``DELETE /v1/{plural}/{name}`` to ``router``."""

    @router.get(
        f"/v1/{plural}/{{name}}",
        name=f"show_{kind}",
        response_model=ItemDetail,
        response_model_exclude_unset=True,
        responses=problems.responses(401, 404, 422),
    )
    def show(request: Request, name: str, who: C.Reader) -> dict:
        """One item: state, metadata, file and its jobs; for a usable ski also its profile model
        (name and why) and its beam: EI(X), c(X) with their bands, the misfit per case and the
        held-out check (the ski's page ``/skis/{name}`` shows the same)."""
        state = C.catalogue_state(request)
        row = C.item_or_404(state, kind, name, who)
        if row.state == "ready":
            state.live.catch_up(kind, name)
        cat = request.app.state.catalogue
        out = {
            **row.public(),
            "usable": name in getattr(cat, plural),
            "jobs": [C.job_view(state.db, j) for j in state.db.jobs(item_id=row.id)],
        }
        if kind == "ski" and name in cat.skis:
            out["profile_model"] = profile_report(cat.skis[name])
            out["beam"] = beam_report(cat.skis[name])
        return out

    @router.patch(
        f"/v1/{plural}/{{name}}",
        name=f"rename_{kind}",
        response_model=ItemView,
        responses=problems.responses(401, 403, 404, 409, 422),
    )
    def rename(request: Request, name: str, body: RenameBody, team: C.Team) -> dict:
        """Rename an uploaded item (shipped items are read-only)."""
        state = C.catalogue_state(request)
        row = C.item_or_404(state, kind, name, C.writer(request, team))
        C.writable(request, row, team)
        new = uploads.check_name(body.name)
        with state.live.lock:
            row = state.db.update_item(row.id, name=new)
            state.live.rename(row)
        return row.public()

    @router.delete(
        f"/v1/{plural}/{{name}}",
        status_code=204,
        name=f"del_{kind}",
        response_class=Response,
        responses=problems.responses(401, 403, 404, 409, 422),
    )
    def delete(request: Request, name: str, team: C.Team) -> Response:
        """Delete an uploaded item and its files (409 while a job uses it)."""
        state = C.catalogue_state(request)
        row = C.item_or_404(state, kind, name, C.writer(request, team))
        C.writable(request, row, team)
        C.busy(state, row)
        with state.live.lock:
            state.live.drop(row.id)
            state.db.delete_item(row.id)
        state.layout.remove_item_files(row.id)
        return Response(status_code=204)

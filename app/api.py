"""The FastAPI application: thin routes over :mod:`app.service`.

Every error a user can cause is a JSON problem body (RFC 9457 shape) with ``status``,
``title``, ``detail`` and, for validation errors, ``errors: [{field, reason}]``; unknown skis or
grinds are 404 with the known names; bodies over the limit are 413; results outside the tables
or non-converged solves are 422 with what to change. Who may change and see what (tokens, the
same-origin check of changes, team filtering) is :mod:`app.access`.
"""

from __future__ import annotations

import logging
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from skisnow.app import api_catalogue, api_flex, service
from skisnow.app.access import WriteGuardMiddleware, visible_catalogue
from skisnow.app.profiles import profile_model
from skisnow.app.schemas import CompareBody, ContactBody
from skisnow.app.settings import Settings
from skisnow.app.web import routes as web_routes
from skisnow.solvers.errors import InputError, NotConvergedError, OutOfRangeError, SkisnowError
from starlette.exceptions import HTTPException as StarletteHTTPException

log = logging.getLogger(__name__)


def problem(status: int, title: str, detail: str, **extra) -> JSONResponse:
    body = {"type": "about:blank", "status": status, "title": title, "detail": detail, **extra}
    return JSONResponse(body, status_code=status, media_type="application/problem+json")


class BodyLimitMiddleware:
    """Refuse bodies larger than ``limit`` bytes with 413 (declared or streamed); POSTs to
    ``upload_paths`` (file uploads) may be up to ``upload_limit`` bytes."""

    def __init__(self, app, limit: int, upload_limit: int = 0, upload_paths=()) -> None:
        self.app = app
        self.limit = limit
        self.upload_limit = upload_limit
        self.upload_paths = tuple(upload_paths)

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        limit = self.limit
        if scope.get("method") == "POST" and scope.get("path") in self.upload_paths:
            limit = max(limit, self.upload_limit)
        headers = dict(scope.get("headers") or [])
        declared = headers.get(b"content-length")
        too_big = problem(413, "Payload Too Large", f"request body exceeds {limit} bytes")
        if declared is not None:
            try:
                if int(declared) > limit:
                    return await too_big(scope, receive, send)
            except ValueError:
                return await problem(400, "Bad Request", "invalid Content-Length")(
                    scope, receive, send
                )
        seen = 0

        async def limited_receive():
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    raise _BodyTooLarge
            return message

        try:
            await self.app(scope, limited_receive, send)
        except _BodyTooLarge:
            await too_big(scope, receive, send)


class _BodyTooLarge(Exception):
    pass


def _named(exc: Exception) -> dict:
    """``errors: [{field, reason}]`` for a service error that names its request field."""
    field = getattr(exc, "field", None)
    return {"errors": [{"field": field, "reason": str(exc)}]} if field else {}


def _field_errors(exc: RequestValidationError) -> list[dict]:
    out = []
    for err in exc.errors():
        loc = [str(p) for p in err.get("loc", ()) if p not in ("body", "query", "path")]
        out.append({"field": ".".join(loc) or "body", "reason": err.get("msg", "invalid")})
    return out


def create_app(settings: Settings | None = None, catalogue: service.Catalogue | None = None):
    """Build the application; the catalogue is loaded (and verified) once at start-up."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        if app.state.catalogue is None:
            app.state.catalogue = service.load_catalogue(settings.tables_dir)
        if settings.warm_up:
            service.warm_up(app.state.catalogue)
        api_catalogue.start(app)
        try:
            yield
        finally:
            api_catalogue.stop(app)

    app = FastAPI(
        title="skisnow",
        version=service.code_version(),
        description=(
            "Multi-scale contact between cross-country skis and snow (Kalliorinne et al. "
            "2022–2023): real contact area, average real contact pressure, minimum average "
            "separation and total reciprocal separation for a ski, a grind, a load and a snow."
        ),
        lifespan=lifespan,
    )
    app.state.catalogue = catalogue
    app.state.settings = settings
    app.add_middleware(
        BodyLimitMiddleware,
        limit=settings.max_body_bytes,
        upload_limit=settings.max_upload_bytes,
        upload_paths=api_catalogue.UPLOAD_PATHS,
    )
    # added last, so it runs first: a refused change never has its body read
    app.add_middleware(
        WriteGuardMiddleware,
        tokens=settings.team_tokens,
        trusted_origins=settings.trusted_origins,
    )

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError):
        errors = _field_errors(exc)
        detail = "; ".join(f"{e['field']}: {e['reason']}" for e in errors)
        return problem(422, "Invalid input", detail, errors=errors)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException):
        return problem(exc.status_code, str(exc.detail), str(exc.detail))

    @app.exception_handler(service.UnknownItemError)
    async def _unknown(request: Request, exc: service.UnknownItemError):
        field = getattr(exc, "field", exc.kind)
        return problem(404, f"Unknown {exc.kind}", str(exc), field=field, known=exc.known)

    @app.exception_handler(OutOfRangeError)
    async def _range(request: Request, exc: OutOfRangeError):
        return problem(422, "Outside the model's range", str(exc), **_named(exc))

    @app.exception_handler(NotConvergedError)
    async def _nc(request: Request, exc: NotConvergedError):
        return problem(422, "Solver did not converge", str(exc))

    @app.exception_handler(InputError)
    async def _input(request: Request, exc: InputError):
        return problem(422, "Invalid input", str(exc), **_named(exc))

    @app.exception_handler(SkisnowError)
    async def _other(request: Request, exc: SkisnowError):
        return problem(422, "Cannot compute this case", str(exc))

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception):
        log.exception("internal error on %s", request.url.path)
        return problem(500, "Internal Server Error", "an internal error occurred; it was logged")

    @app.get("/healthz", tags=["ops"])
    def healthz() -> dict:
        """Liveness: the process answers."""
        return {"status": "ok"}

    @app.get("/readyz", tags=["ops"])
    def readyz(request: Request) -> JSONResponse:
        """Readiness: tables and ski files loaded and verified against their manifests."""
        if app.state.catalogue is None:
            return problem(503, "Not ready", "catalogue not loaded")
        cat = visible_catalogue(request)
        return JSONResponse(
            {"status": "ready", "skis": sorted(cat.skis), "grinds": sorted(cat.grinds)}
        )

    @app.get("/v1/skis", tags=["catalogue"])
    def list_skis(request: Request) -> dict:
        """Skis with their outline, model and file provenance."""
        cat = visible_catalogue(request, fresh=True)
        out = []
        for s in cat.skis.values():
            lo, hi = s.position_range_m
            o = s.record.outline
            net = s.record.network
            out.append(
                {
                    "name": s.name,
                    "length_mm": o.length_m * 1e3,
                    "width_mm": [float(w) * 1e3 for w in o.width_m],
                    "load_position_range_mm": [lo * 1e3, hi * 1e3],
                    "profile_model": profile_model(s.record).source,
                    "profile_model_reason": profile_model(s.record).reason,
                    "network_metrics": (net or {}).get("attrs", {}).get("metrics_json"),
                    "description": s.record.metadata.get("description"),
                    "file": s.path.name,
                    "sha256": s.sha256,
                }
            )
        return {"skis": out}

    @app.get("/v1/grinds", tags=["catalogue"])
    def list_grinds(request: Request) -> dict:
        """Grinds with their ISO 25178 parameters and table provenance."""
        cat = visible_catalogue(request, fresh=True)
        out = []
        for g in cat.grinds.values():
            t = g.table
            out.append(
                {
                    "name": g.name,
                    "iso25178": t.iso_parameters,
                    "texture_pixel_size_um": t.pixel_size_m * 1e6,
                    "grid": list(t.grid_shape),
                    "pressure_ratio_range": [
                        float(t.pressure_ratio[0]),
                        float(t.pressure_ratio[-1]),
                    ],
                    "gap_floor_nm": t.gap_floor_m * 1e9,
                    # what was removed from the heights (plane, mean, none); None: not recorded
                    "detrend": t.attrs.get("texture_detrend"),
                    "file": g.path.name,
                    "sha256": g.sha256,
                    "code_version": t.attrs.get("code_version"),
                    "git_commit": t.attrs.get("git_commit"),
                }
            )
        return {"grinds": out}

    # The answers are plain JSON types already (lists of floats from service._finite_list), so
    # they go out as a JSONResponse: FastAPI's jsonable_encoder would walk their ~10^4 values
    # again (8-10 ms of a ~60 ms request on the benchmark machine) to give the same bytes.
    @app.post("/v1/contact", tags=["contact"], response_model=dict)
    def post_contact(request: Request, body: ContactBody) -> JSONResponse:
        """One ski × grind case: metrics, apparent contact, distributions, provenance."""
        return JSONResponse(
            service.contact(
                visible_catalogue(request, skis=[body.ski], grinds=[body.grind]),
                service.ContactInputs(**body.model_dump()),
            )
        )

    @app.post("/v1/compare", tags=["contact"], response_model=dict)
    def post_compare(request: Request, body: CompareBody) -> JSONResponse:
        """Every ski × grind combination for one load and snow."""
        cells = len(body.skis) * len(body.grinds)
        if cells > settings.max_compare_cells:
            return problem(
                422,
                "Invalid input",
                f"skis × grinds = {cells} cases exceeds the limit of {settings.max_compare_cells}",
                errors=[{"field": "skis", "reason": "too many combinations"}],
            )
        cat = visible_catalogue(request, skis=body.skis, grinds=body.grinds)
        for s in body.skis:
            cat.ski(s)
        for g in body.grinds:
            cat.grind(g)
        common = body.model_dump(exclude={"skis", "grinds"})
        results = []
        for s in body.skis:
            for g in body.grinds:
                results.append(
                    service.contact(cat, service.ContactInputs(ski=s, grind=g, **common))
                )
        return JSONResponse({"results": results})

    api_flex.mount(app)
    api_catalogue.mount(app)
    web_routes.mount(app)
    return app

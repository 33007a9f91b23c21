"""The routes of the HTML pages (all ``GET`` so that every result is a link; none in the OpenAPI
schema). Each reads the request, asks one page module for its page, and returns it.

``/``
    The contact form (:mod:`.form`): skis and grinds from the catalogue, load [kg] and its
    position [mm] with presets, snow modulus [MPa] and porosity (or snow density [kg/m³]),
    advanced base modulus and Poisson's ratio. Query parameters, if any, pre-fill it.
``/results``, ``/results.csv``
    The four metrics for every ski × grind, a comparison table, plots and provenance; the
    comparison table as CSV (:mod:`.results`).
``/skis/{name}``
    One ski's page (:mod:`.ski_page`); an unknown name is a 404 page.
``/upload``, ``/upload/example-camber.csv``
    Upload a ski's camber CSV or a grind's topography (:mod:`.upload_page`); an example camber
    CSV from a demo ski's measurements.
``/flex``, ``/flex/pair``, ``/flex/ranking``
    The flex tab (:mod:`.flex_pages`).
``/login``, ``POST /login``, ``POST /logout``
    Token mode for people: a team token becomes the login cookie (:mod:`.login`).
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.responses import HTMLResponse, Response
from skisnow.app import service
from skisnow.app.api.access import caller, visible_catalogue
from skisnow.app.storage.layout import Layout
from skisnow.app.web import flex_pages, login
from skisnow.app.web.form import (
    LAST_USED_COOKIE,
    Query,
    failure_field,
    last_used_cookie,
    parse_query,
    render_form,
)
from skisnow.app.web.results import ResultCache, compute, render_csv, render_results
from skisnow.app.web.ski_page import render_ski, render_unknown_ski
from skisnow.app.web.upload_page import EXAMPLE_CSV_URL, example_camber_csv, render_upload


def mount(app: FastAPI) -> None:
    """Add every page route to ``app``."""
    cache = ResultCache()

    def _named_catalogue(request: Request) -> service.Catalogue:
        qp = request.query_params
        return visible_catalogue(request, skis=qp.getlist("ski"), grinds=qp.getlist("grind"))

    def _query(request: Request, cat: service.Catalogue) -> Query:
        return parse_query(request, cat, request.app.state.settings.max_compare_cells)

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def form(request: Request) -> HTMLResponse:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not request.query_params:
            q.errors.clear()
        # a pre-filled form shows only the errors of what was given
        elif not q.skis and not q.grinds:
            q.errors.pop("ski", None)
            q.errors.pop("grind", None)
        return render_form(request, cat, q)

    @app.get("/results", response_class=HTMLResponse, include_in_schema=False)
    def results(request: Request) -> HTMLResponse:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not q.ok:
            return render_form(request, cat, q, q.status)
        out = compute(cat, q, cache)
        if not out.results:
            for inp, msg in out.failures:
                q.errors.setdefault(failure_field(msg), f"{inp.ski} × {inp.grind}: {msg}")
            return render_form(request, cat, q, 422)
        response = render_results(request, q, out)
        # the form's next defaults: these skis and grinds (a year; the browser's only)
        response.set_cookie(
            LAST_USED_COOKIE, last_used_cookie(q), max_age=365 * 86400, samesite="lax"
        )
        return response

    @app.get("/skis/{name:path}", response_class=HTMLResponse, include_in_schema=False)
    def ski_page(request: Request, name: str) -> HTMLResponse:
        cat = visible_catalogue(request, skis=[name])
        ski = cat.skis.get(name)
        if ski is None:
            state = None
            uploads_state = getattr(request.app.state, "uploads", None)
            if uploads_state is not None:
                row = uploads_state.db.item_by_name("ski", name)
                if row is not None and caller(request).sees(row.team, row.read_only):
                    state = row.state
            return render_unknown_ski(request, cat, name, state)
        settings = getattr(request.app.state, "settings", None)
        figure_cache = None
        if settings is not None:
            figure_cache = Layout(Path(settings.data_dir)).ski_figures(ski.path.stem)
        return render_ski(request, cat, ski, figure_cache)

    @app.get("/upload", response_class=HTMLResponse, include_in_schema=False)
    def upload(request: Request) -> HTMLResponse:
        return render_upload(request, visible_catalogue(request), request.app.state.settings)

    @app.get(EXAMPLE_CSV_URL, include_in_schema=False)
    def example_csv() -> Response:
        return Response(
            example_camber_csv(),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": 'attachment; filename="example-camber.csv"'},
        )

    @app.get("/results.csv", include_in_schema=False)
    def results_csv(request: Request) -> Response:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not q.ok:
            return render_form(request, cat, q, q.status)
        out = compute(cat, q, cache)
        return Response(
            render_csv(out),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": 'attachment; filename="skisnow-contact.csv"'},
        )

    @app.get(login.LOGIN_URL, response_class=HTMLResponse, include_in_schema=False)
    def login_page(request: Request) -> HTMLResponse:
        return login.render_login(request, next_url=request.query_params.get("next", "/"))

    @app.post(login.LOGIN_URL, include_in_schema=False)
    async def login_post(request: Request) -> Response:
        form = await request.form()
        return login.login(request, form.get("token"), form.get("next", "/"))

    @app.post("/logout", include_in_schema=False)
    def logout_post(request: Request) -> Response:
        return login.logout(request)

    @app.get("/flex", response_class=HTMLResponse, include_in_schema=False)
    def flex_page(request: Request) -> HTMLResponse:
        return flex_pages.render_sheet(request)

    @app.get("/flex/pair", response_class=HTMLResponse, include_in_schema=False)
    def pair_page(request: Request) -> HTMLResponse:
        return flex_pages.render_pair(request)

    @app.get("/flex/ranking", response_class=HTMLResponse, include_in_schema=False)
    def ranking_page(request: Request) -> HTMLResponse:
        return flex_pages.render_ranking(request)

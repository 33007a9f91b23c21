"""The Jinja2 environment of the pages (autoescape on) and the one way to answer with a page.

Every page extends ``templates/page.html``. Values are escaped by Jinja2; the only text that
reaches a page unescaped (as :class:`markupsafe.Markup`) is

- the CSS and JavaScript of ``static/``, inlined in the page (files of this package);
- the SVG figures of :mod:`.plots` (drawn by matplotlib from the answers' numbers; the few
  labels that carry names, such as a legend's ski × grind, are escaped by matplotlib's SVG
  writer, which also renders text as paths), passed through :func:`svg`.

No Python code here or in the page modules calls ``html.escape``.
"""

from __future__ import annotations

import math
from importlib import resources

from fastapi import Request
from fastapi.responses import HTMLResponse
from fastapi.templating import Jinja2Templates
from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup
from skisnow.app import service


def fmt(value, spec: str = "{:.4g}") -> str:
    """A number as the pages print it; ``–`` for none or not finite."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return spec.format(value)


def num(value, digits: int = 4) -> str:
    """A value of the flex pages: ``–`` for none or not finite, yes/no for a bool, floats to
    ``digits`` significant digits, anything else as text."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def pm(value, band, digits: int = 4) -> str:
    """``value ± band`` (the band to 2 digits), or the value alone without a band."""
    text = num(value, digits)
    if band:
        text += f" ± {num(band, 2)}"
    return text


def svg(text: str) -> Markup:
    """An SVG figure of :mod:`.plots` to inline as it is (see the module docstring)."""
    return Markup(text)


def _static(name: str) -> Markup:
    return Markup(resources.files("skisnow.app.web").joinpath(f"static/{name}").read_text("utf-8"))


#: the inline style and script of the pages (``static/``)
CSS = _static("web.css")
JS = _static("web.js")
UPLOAD_CSS = _static("upload.css")
UPLOAD_JS = _static("upload.js")
DELETE_JS = _static("delete.js")

ENV = Environment(
    loader=PackageLoader("skisnow.app.web", "templates"),
    autoescape=True,
    trim_blocks=True,
    lstrip_blocks=True,
    undefined=StrictUndefined,
    keep_trailing_newline=True,
)
ENV.filters.update(fmt=fmt, num=num, pm=pm)
templates = Jinja2Templates(env=ENV)


def page(
    request: Request,
    template: str,
    title: str,
    status: int = 200,
    *,
    css: Markup = CSS,
    js: Markup = JS,
    **context,
) -> HTMLResponse:
    """The page ``template`` (which extends ``page.html``) with ``context``."""
    context.setdefault("login", login_state(request))
    return templates.TemplateResponse(
        request,
        template,
        {"title": title, "css": css, "js": js, "version": service.code_version(), **context},
        status_code=status,
    )


def login_state(request: Request) -> dict:
    """The page header's login: whether teams are on, the caller's team (the login cookie,
    :mod:`.login`) and the login link back to this page."""
    from urllib.parse import urlencode

    from skisnow.app.api.access import caller

    settings = getattr(request.app.state, "settings", None)
    if settings is None or not settings.team_tokens:
        return {"teams_on": False, "team": None, "url": "/login"}
    here = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    return {
        "teams_on": True,
        "team": caller(request).team,
        "url": "/login?" + urlencode({"next": here}),
    }

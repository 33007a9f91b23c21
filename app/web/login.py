"""The login page ``/login`` and ``POST /logout``: token mode for people (app/api/access.py).

With team tokens (``SKISNOW_TEAM_TOKENS``) a browser adds no ``Authorization`` header, so a
person logs in once: ``POST /login`` with the team token answers a redirect that sets the
cookie :data:`~app.api.access.TOKEN_COOKIE` (the token itself; HttpOnly, so no script of a
page can read it; SameSite=Strict, so no other site's page makes the browser send it; Secure
when the page was served over https; it lasts :data:`LOGIN_MAX_AGE_S`). Every page and route
then takes the cookie for the token: the contact form lists the team's uploads, the upload
page follows the team's jobs, the job's "compute a contact" link opens the form with the new
item. ``POST /logout`` removes the cookie. Both forms pass the same-origin check of the write
guard (a login from another site's page is refused). Without team tokens there is nothing to
log in to: the page says so and ``POST /login`` is 404.
"""

from __future__ import annotations

from fastapi import Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from skisnow.app.api.access import TOKEN_COOKIE, caller
from skisnow.app.web.templating import page

__all__ = ["LOGIN_MAX_AGE_S", "LOGIN_URL", "login", "logout", "render_login", "safe_next"]

LOGIN_URL = "/login"
#: how long the login cookie lasts [s]: a week (a login per week of a shop's laptop)
LOGIN_MAX_AGE_S = 7 * 24 * 3600
#: the longest team token the form takes [characters]
MAX_TOKEN_CHARS = 512


def safe_next(value) -> str:
    """Where to go after the login: a path of this service (``/...``), else ``/`` (never
    another site: ``//host`` and ``/\\host`` are refused)."""
    if not isinstance(value, str) or not value.startswith("/") or value.startswith(("//", "/\\")):
        return "/"
    if any(ord(ch) < 0x20 for ch in value) or len(value) > 2000:
        return "/"
    return value


def render_login(
    request: Request, *, error: str | None = None, status: int = 200, next_url: str = "/"
) -> HTMLResponse:
    """The login form (and who is logged in)."""
    return page(
        request,
        "login.html",
        "skisnow — log in",
        status,
        error=error,
        next_url=safe_next(next_url),
        teams_on=bool(request.app.state.settings.team_tokens),
        team=caller(request).team,
    )


def _cookie_args(request: Request) -> dict:
    return {
        "path": "/",
        "httponly": True,
        "samesite": "strict",
        "secure": request.url.scheme == "https",
    }


def login(request: Request, token, next_url) -> Response:
    """``POST /login``: a team token → 303 to ``next_url`` with the login cookie; an unknown
    token → the form again with the reason (401); no team tokens → 404."""
    tokens = request.app.state.settings.team_tokens
    if not tokens:
        return render_login(
            request,
            error="this service has no team tokens (SKISNOW_TEAM_TOKENS): nothing to log in to",
            status=404,
        )
    token = token.strip() if isinstance(token, str) else ""
    if not token or len(token) > MAX_TOKEN_CHARS or token not in tokens:
        what = "no team token was given" if not token else "that is not a team token"
        return render_login(
            request,
            error=f"{what}; ask the service's operator for your team's token",
            status=401,
            next_url=next_url,
        )
    resp = RedirectResponse(safe_next(next_url), status_code=303)
    resp.set_cookie(TOKEN_COOKIE, token, max_age=LOGIN_MAX_AGE_S, **_cookie_args(request))
    return resp


def logout(request: Request) -> Response:
    """``POST /logout``: remove the login cookie, then the contact form (303)."""
    resp = RedirectResponse("/", status_code=303)
    resp.delete_cookie(TOKEN_COOKIE, **_cookie_args(request))
    return resp

"""Who may reach the service, and who may change and see what: the service's access rules
(docs/uploads.md, "Access").

Hosts
    Every request is checked by :class:`HostGuardMiddleware` before routing: its ``Host``
    header must name a host of :func:`allowed_hosts` (loopback names and addresses, the
    listening host, the hosts of ``Settings.trusted_origins`` and ``Settings.allowed_hosts``),
    else 421 (Misdirected Request) with a problem body. ``GET /healthz`` and ``/readyz``
    (:data:`PROBE_PATHS`, which change and show nothing) are not checked: an orchestrator's
    probe names the container's address. Without this check a DNS-rebinding
    page (``evil.example`` re-pointed at 127.0.0.1) is same-origin with the service by its own
    ``Host`` and passes the check of changes below.

Changes
    Every request with a method in :data:`WRITE_METHODS` (uploads, renames, deletes, and so the
    jobs they queue) is checked by :class:`WriteGuardMiddleware` before its body is read:

    - with team tokens (``Settings.team_tokens``) it needs ``Authorization: Bearer TOKEN`` of a
      team, else 401. A browser never adds that header on its own, so another site's page
      cannot make a technician's browser send it;
    - without team tokens (the default) it must come from the service's own origin: a request
      whose ``Origin`` header, or ``Referer`` when it has no ``Origin``, names another origin
      than its ``Host`` (or one of ``Settings.trusted_origins``) is refused with 403 naming
      both. Browsers send ``Origin`` with every cross-origin POST, PATCH and DELETE, so a page
      on another site that posts a form or a ``fetch`` to ``127.0.0.1:8000`` is refused, while
      the service's own upload page (same origin) and clients that send neither header (curl,
      scripts, a team's tools) pass.

    ``POST /v1/contact``, ``POST /v1/compare`` and ``POST /v1/flex/ranking``
    (:data:`READ_ONLY_POSTS`) are computations that change nothing: they are not checked.
    Another site can make a browser send one, but cannot read its answer (the service sends no
    CORS headers), and the CPU it costs is open to anyone who reaches the port through those
    routes anyway (``max_compare_cells`` bounds it).

The login cookie
    People use the pages, and a browser adds no ``Authorization`` header: the login page
    (``/login``, :mod:`app.web.login`) turns a team token into the cookie
    :data:`TOKEN_COOKIE` (HttpOnly, SameSite=Strict, Secure over https), which every page and
    route honour as that token (:func:`request_team`; an ``Authorization`` header, when sent,
    decides). A browser sends the cookie on its own, so a change it authorises must also pass
    the same-origin check (403 otherwise): SameSite=Strict keeps it from other sites, the
    check from other origins of the same site (another port of the same host). The login and
    logout forms (:data:`LOGIN_PATHS`) need no token, only the same-origin check. A cookie
    whose token is no longer configured reads as no team, and a change with it is 401.

Items of no team
    With team tokens the uploads of no team (made before teams were configured) are seen by
    every team but changed by none (403, :func:`team_may_change`), until ``skisnow adopt``
    assigns them to a team (docs/deployment.md).

Reads
    Without team tokens everyone sees everything. With team tokens a caller (:class:`Caller`,
    the team of its bearer token; no token: a caller of no team) sees the shipped items, the
    uploads of no team (made before teams were configured) and its own team's, in every list,
    item, job, contact computation and web page. Another team's item or job answers 404 as if
    it did not exist. An invalid token is 401.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from urllib.parse import urlsplit

from skisnow.app import service
from skisnow.app.errors import UnauthorizedError
from starlette.datastructures import Headers
from starlette.requests import Request, cookie_parser

__all__ = [
    "LOGIN_PATHS",
    "LOOPBACK_NAMES",
    "PROBE_PATHS",
    "READ_ONLY_POSTS",
    "TOKEN_COOKIE",
    "WRITE_METHODS",
    "Caller",
    "HostGuardMiddleware",
    "WriteGuardMiddleware",
    "allowed_hosts",
    "bearer_team",
    "caller",
    "cookie_token",
    "cross_origin_reason",
    "failed_views",
    "host_refusal",
    "request_team",
    "team_may_change",
    "visible_catalogue",
]

#: methods that change the catalogue (or queue jobs)
WRITE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})
#: POST routes that only compute and change nothing (not checked, see the module docstring)
READ_ONLY_POSTS = frozenset({"/v1/contact", "/v1/compare", "/v1/flex/ranking"})
#: the login and logout forms of the pages: no token needed, the same-origin check applies
LOGIN_PATHS = frozenset({"/login", "/logout"})
#: the cookie of the login page that carries a team token (see the module docstring)
TOKEN_COOKIE = "skisnow_token"
_DEFAULT_PORTS = {"http": 80, "https": 443}
#: host names that always mean this machine (RFC 6761: ``*.localhost`` too); loopback
#: addresses (127.0.0.0/8, ::1) are recognised by value
LOOPBACK_NAMES = frozenset({"localhost"})
#: liveness and readiness probes, answered whatever the Host (see the module docstring)
PROBE_PATHS = frozenset({"/healthz", "/readyz"})
#: the host of Starlette's in-process test client; allowed only for a request whose client is
#: that test client (``scope["client"]``), never one that came over a socket
_TEST_HOST, _TEST_CLIENT = "testserver", "testclient"
#: listening addresses that mean "every interface": no host name follows from them
_WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::", "[::]"})
#: at most this many names of each kind per request are looked up in the database when this
#: process does not serve them (see :func:`visible_catalogue`)
_CATCH_UP_MAX = 64


# ------------------------------------------------------------------------------ teams


def bearer_team(headers: Mapping[str, str], tokens: Mapping[str, str], *, required: bool):
    """The team of the request's ``Authorization: Bearer TOKEN`` (None: no header and not
    ``required``).

    Raises
    ------
    UnauthorizedError
        A header with an unknown token or another scheme, or none when ``required``.
    """
    auth = headers.get("authorization", "")
    if not auth and not required:
        return None
    scheme, _, token = auth.partition(" ")
    token = token.strip()
    if scheme.lower() != "bearer" or token not in tokens:
        what = "to change the catalogue" if required else "(or no Authorization header)"
        raise UnauthorizedError(
            f"a valid bearer token is required {what}: send Authorization: Bearer TOKEN, or "
            "log in with the team token at /login (web pages)"
        )
    return tokens[token]


def cookie_token(headers: Mapping[str, str]) -> str | None:
    """The team token of the login cookie :data:`TOKEN_COOKIE` (None: no such cookie)."""
    raw = headers.get("cookie")
    if not raw:
        return None
    return cookie_parser(raw).get(TOKEN_COOKIE) or None


def request_team(headers: Mapping[str, str], tokens: Mapping[str, str], *, required: bool):
    """The team of a request: its ``Authorization`` header when it has one
    (:func:`bearer_team`), else its login cookie; None for a caller of no team (not
    ``required``).

    A login cookie whose token is not (or no longer) configured reads as no team; when
    ``required`` it is :class:`UnauthorizedError`, asking to log in again.
    """
    if not headers.get("authorization"):
        token = cookie_token(headers)
        if token is not None and token in tokens:
            return tokens[token]
        if token is not None and required:
            raise UnauthorizedError(
                "the team token of your login is no longer valid; log in again at /login"
            )
    return bearer_team(headers, tokens, required=required)


def team_may_change(owner: str | None, team: str | None, teams_on: bool) -> str | None:
    """Why ``team`` may not change an upload of team ``owner`` (None: it may). With teams
    on, the uploads of no team are read-only (see the module docstring)."""
    if not teams_on:
        return None
    if owner is None:
        return (
            "was uploaded before team tokens were switched on and belongs to no team: it is "
            "read-only until an operator assigns it to a team (skisnow adopt, "
            "docs/deployment.md)"
        )
    if owner != team:
        return "belongs to another team"
    return None


@dataclass(frozen=True)
class Caller:
    """Who is asking: the team (None: no team) and whether teams are configured at all."""

    team: str | None
    teams_on: bool

    def sees(self, owner: str | None, read_only: bool = False) -> bool:
        """Whether this caller may see an item of team ``owner`` (shipped: ``read_only``)."""
        return not self.teams_on or read_only or owner is None or owner == self.team


def caller(request: Request) -> Caller:
    """The :class:`Caller` of a request (a FastAPI dependency; 401 for an invalid token)."""
    tokens = request.app.state.settings.team_tokens
    if not tokens:
        return Caller(None, False)
    return Caller(request_team(request.headers, tokens, required=False), True)


def visible_catalogue(
    request: Request, skis: Iterable[str] = (), grinds: Iterable[str] = (), fresh: bool = False
) -> service.Catalogue:
    """The served catalogue as the request's caller sees it: without another team's uploads
    (the same object when teams are off or nothing is hidden).

    ``skis`` and ``grinds`` are the names the request asks for. One that this process has not
    loaded yet but the database holds ready (another process's job finished it; this one's
    poll would load it within ``job_poll_s``) is loaded now, so that a client who saw the job
    done can use the item at once, whichever process answers. ``fresh`` brings the whole
    catalogue up to the database first (one query; the lists use it)."""
    state = getattr(request.app.state, "uploads", None)
    if state is not None and fresh:
        state.live.sync()
    elif state is not None:
        for kind, names in (("ski", skis), ("grind", grinds)):
            for name in list(names)[:_CATCH_UP_MAX]:
                state.live.catch_up(kind, name)
    cat = request.app.state.catalogue
    who = caller(request)
    if not who.teams_on or state is None:
        return cat
    hidden = state.live.owned_by_others(who.team)
    if not hidden:
        return cat
    return replace(
        cat,
        skis={n: s for n, s in cat.skis.items() if ("ski", n) not in hidden},
        grinds={n: g for n, g in cat.grinds.items() if ("grind", n) not in hidden},
    )


# ------------------------------------------------------------------------------- hosts


def _host_name(host_header: str) -> str | None:
    """The host name of a ``Host`` header (lower case, no port, no brackets, no final dot);
    None when it is not one."""
    try:
        parts = urlsplit("//" + host_header.strip())
        parts.port  # noqa: B018 - raises ValueError on a bad port
    except ValueError:
        return None
    name = (parts.hostname or "").rstrip(".")
    return name or None


def _is_loopback(name: str) -> bool:
    if name in LOOPBACK_NAMES or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def allowed_hosts(settings) -> frozenset[str]:
    """Host names a request's ``Host`` may name besides loopback (:func:`host_refusal`): the
    listening host (unless it is every interface, ``0.0.0.0``/``::``), the hosts of
    ``trusted_origins`` and ``allowed_hosts`` (``"*"``: any)."""
    names = set()
    host = str(settings.host).strip().lower()
    if host not in _WILDCARD_HOSTS:
        names.add(host.strip("[]").rstrip("."))
    for origin in settings.trusted_origins:
        parsed = _origin(origin)
        if parsed is not None:
            names.add(parsed[1].rstrip("."))
    for entry in settings.allowed_hosts:
        entry = entry.strip().lower()
        if entry == "*":
            names.add("*")
        elif entry:
            names.add(_host_name(entry) or entry)
    return frozenset(names)


def host_refusal(host_header: str | None, allowed: frozenset[str], client=None) -> str | None:
    """Why a request naming ``host_header`` may not reach the service, or None when it may.

    A request without ``Host`` passes (browsers always send one: a DNS-rebinding page cannot
    leave it out). ``client`` is the ASGI ``scope["client"]``: Starlette's test client alone
    may name ``testserver``."""
    if host_header is None or "*" in allowed:
        return None
    name = _host_name(host_header)
    if name is not None and (name in allowed or _is_loopback(name)):
        return None
    if name == _TEST_HOST and client is not None and client[0] == _TEST_CLIENT:
        return None
    return (
        f"Host {host_header!r} is not a name of this service; requests must name localhost, "
        "a loopback address, the listening host (SKISNOW_HOST) or a host of "
        "SKISNOW_TRUSTED_ORIGINS or SKISNOW_ALLOWED_HOSTS (refused before routing: a web page "
        "whose name was re-pointed at this machine must not reach it)"
    )


class HostGuardMiddleware:
    """Refuse every request whose ``Host`` is not allowed (:func:`host_refusal`) with 421,
    before routing and before its body is read."""

    def __init__(self, app, allowed: Iterable[str]) -> None:
        self.app = app
        self.allowed = frozenset(allowed)

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or (
            scope.get("path") in PROBE_PATHS and scope.get("method") in ("GET", "HEAD")
        ):
            return await self.app(scope, receive, send)
        host = Headers(scope=scope).get("host")
        reason = host_refusal(host, self.allowed, scope.get("client"))
        if reason is None:
            return await self.app(scope, receive, send)
        from skisnow.app.api.problems import problem

        return await problem(421, "Misdirected Request", reason)(scope, receive, send)


# ----------------------------------------------------------------------------- origins


def _origin(url: str) -> tuple[str, str, int] | None:
    """(scheme, host, port) of an http(s) URL or origin; None for anything else ("null")."""
    try:
        parts = urlsplit(url.strip())
        port = parts.port
    except ValueError:
        return None
    if parts.scheme not in _DEFAULT_PORTS or not parts.hostname:
        return None
    return parts.scheme, parts.hostname.lower(), port or _DEFAULT_PORTS[parts.scheme]


def _same_host(origin: tuple[str, str, int], host_header: str) -> bool:
    """Whether ``origin`` is the origin the request was sent to, by its ``Host`` header (a
    ``Host`` without a port is the default port of the origin's scheme)."""
    try:
        parts = urlsplit("//" + host_header.strip())
        port = parts.port
    except ValueError:
        return False
    if not parts.hostname:
        return False
    return parts.hostname.lower() == origin[1] and (port or _DEFAULT_PORTS[origin[0]]) == origin[2]


def cross_origin_reason(
    headers: Mapping[str, str], trusted=(), scheme: str | None = None, *, cookie: bool = False
) -> str | None:
    """Why a change may not pass the same-origin check, or None when it may.

    The request's origin is its ``Origin`` header, else the origin of its ``Referer``; with
    neither it passes (not sent by a browser page). It passes when that origin is the
    request's own (its ``scheme``, ``http`` or ``https`` as the server received it; None: not
    compared, and its ``Host``) or one of ``trusted`` (``scheme://host[:port]``). ``cookie``:
    the change is authorised by the login cookie (the reason says so).
    """
    header, value = "Origin", headers.get("origin")
    if value is None:
        header, value = "Referer", headers.get("referer")
    if value is None:
        return None
    origin = _origin(value)
    host = headers.get("host", "")
    if origin is not None:
        own = _same_host(origin, host) and (scheme is None or origin[0] == scheme)
        if own or origin in {_origin(t) for t in trusted}:
            return None
    shown = value if header == "Origin" else f"{value!r} (origin of the Referer)"
    if cookie:
        return (
            f"cross-origin change refused: {header} {shown} is not this service's origin "
            f"(Host {host!r}). A login, and a change authorised by the login cookie, must "
            "come from the service's own pages (other clients send Authorization: Bearer "
            "TOKEN); list a trusted origin in SKISNOW_TRUSTED_ORIGINS"
        )
    return (
        f"cross-origin change refused: {header} {shown} is not this service's origin "
        f"({scheme + '://' if scheme else ''}{host or '(no Host)'}). Without team tokens "
        "(SKISNOW_TEAM_TOKENS) uploads, renames and deletes must come from the service's own "
        "pages, or from a client that sends no Origin "
        "or Referer (curl, scripts); list a trusted origin in SKISNOW_TRUSTED_ORIGINS"
    )


class WriteGuardMiddleware:
    """Check every change (:data:`WRITE_METHODS`, minus :data:`READ_ONLY_POSTS`) before its
    body is read: a team's bearer token or login cookie when ``tokens`` are set (401), and
    the same-origin check (403) without tokens, for a change the login cookie authorises,
    and for the login forms (:data:`LOGIN_PATHS`). See the module docstring."""

    def __init__(self, app, tokens: Mapping[str, str], trusted_origins=()) -> None:
        self.app = app
        self.tokens = dict(tokens)
        self.trusted = tuple(trusted_origins)

    async def __call__(self, scope, receive, send):
        if (
            scope["type"] != "http"
            or scope.get("method") not in WRITE_METHODS
            or scope.get("path") in READ_ONLY_POSTS
        ):
            return await self.app(scope, receive, send)
        from skisnow.app.api.problems import problem

        headers = Headers(scope=scope)
        # the login cookie, not a header the client chose to send, authorises this change
        by_cookie = bool(self.tokens) and not headers.get("authorization")
        if self.tokens and scope.get("path") not in LOGIN_PATHS:
            try:
                request_team(headers, self.tokens, required=True)
            except UnauthorizedError as exc:
                resp = problem(401, "Unauthorized", str(exc))
                resp.headers["WWW-Authenticate"] = "Bearer"
                return await resp(scope, receive, send)
        if not self.tokens or by_cookie or scope.get("path") in LOGIN_PATHS:
            reason = cross_origin_reason(
                headers, self.trusted, scope.get("scheme"), cookie=bool(self.tokens)
            )
            if reason is not None:
                return await problem(403, "Forbidden", reason)(scope, receive, send)
        return await self.app(scope, receive, send)


def failed_views(request: Request, kind: str) -> list[dict]:
    """The failed ``kind`` items the request's caller may see, each with its reason (the
    failed job's error), for the lists ``GET /v1/skis`` and ``/v1/grinds`` and the upload
    page."""
    state = getattr(request.app.state, "uploads", None)
    if state is None:
        return []
    who = caller(request)
    out = []
    for item, job in state.db.failed_items(kind):
        if not who.sees(item.team, item.read_only):
            continue
        out.append(
            {
                "name": item.name,
                "reason": (job.error if job else None) or "no reason recorded",
                "job": job.id if job else None,
                "failed_at": (job or item).updated_at.isoformat(timespec="seconds"),
            }
        )
    return out

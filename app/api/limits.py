"""Request body limits: refuse large bodies with a 413 problem before a route reads them."""

from __future__ import annotations

from skisnow.app.api.problems import problem

__all__ = ["BodyLimitMiddleware"]


class BodyLimitMiddleware:
    """Refuse bodies larger than ``limit`` bytes with 413 (declared or streamed); POSTs to
    ``upload_paths`` (file uploads) may be up to ``upload_limit`` bytes.

    A body without ``Content-Length`` (``Transfer-Encoding: chunked``) is counted as it is
    read: the read that passes the limit raises inside the app, and the app's answer, whatever
    it is (FastAPI answers an exception while parsing a form with 400), is replaced by the 413.
    """

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
        over = False
        started = False

        async def limited_receive():
            nonlocal seen, over
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    over = True
                    raise _BodyTooLarge
            return message

        async def guarded_send(message):
            # once the body went over the limit, whatever the app answers (FastAPI turns an
            # exception while parsing a form into 400 "error parsing the body") is replaced
            # by the 413
            nonlocal started
            if over:
                return
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, limited_receive, guarded_send)
        except _BodyTooLarge:
            pass
        if over and not started:
            await too_big(scope, receive, send)


class _BodyTooLarge(Exception):
    pass

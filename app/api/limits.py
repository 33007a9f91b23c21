"""Request body limits: refuse large bodies with a 413 problem before a route reads them."""

from __future__ import annotations

from skisnow.app.api.problems import problem

__all__ = ["BodyLimitMiddleware"]


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

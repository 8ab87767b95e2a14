"""The request body limit: an ASGI middleware that answers 413 to bodies over the service's limit."""
from __future__ import annotations

import json
from typing import Any

from fusioncut.errors import FusionCutError


class BodyTooLarge(FusionCutError):
    """A request body over the limit (``Settings.max_upload_bytes``); answered 413 with the message."""

    def __init__(self, limit: int):
        super().__init__(f"request body larger than the limit of {limit / 1024 / 1024:.1f} MiB")


class BodyLimit:
    """Refuse request bodies over ``limit`` bytes with 413: at once when Content-Length says so, and
    while reading when the body is streamed without one (the form parser would spool it all first)."""

    def __init__(self, app: Any, limit: int):
        self.app = app
        self.limit = limit

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http" or scope["method"] not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        if length is not None and length.isdigit() and int(length) > self.limit:
            await send_problem(send, 413, str(BodyTooLarge(self.limit)))
            return
        received = 0
        started = False

        async def limited_receive() -> dict:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.limit:
                    raise BodyTooLarge(self.limit)
            return message

        async def tracking_send(message: dict) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except BodyTooLarge as exc:
            if not started:
                await send_problem(send, 413, str(exc))


async def send_problem(send: Any, status: int, detail: str) -> None:
    """Answer ``{"detail": detail}`` with ``status`` at the ASGI level (outside FastAPI's handlers)."""
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})

"""Request bodies, bounded before anything reads them: every route has a size limit (a few routes
a larger one) and a body must keep arriving. Enforced on the raw ASGI stream, before routing,
authentication or parsing, so an anonymous client cannot make the server read, spool or parse
more than a route allows, nor hold a connection by sending slowly.

A declared Content-Length over the limit is refused at once; a streamed body is counted as it
arrives and cut at the limit. Either way the client gets a JSON 413 (408 for a stalled body, or
one that trickles in slower than MIN_BODY_RATE once twice read_timeout_s is over) and the
application sees the client disconnect. Once the body is in, what the application receives (the
client leaving, while a response streams) is not timed.
"""
from __future__ import annotations

import asyncio
import json
from collections.abc import Mapping
from dataclasses import dataclass

from starlette.types import ASGIApp, Message, Receive, Scope, Send

KB = 1024
MIN_BODY_RATE = 8 * KB  # bytes/s a body must average past twice its read timeout: no trickle holds a connection


@dataclass(frozen=True)
class Limit:
    size: int  # bytes of body
    refusal: str  # the 413's detail

    @classmethod
    def of(cls, size: int, what: str = "request body", shown: int | None = None) -> Limit:
        """A limit whose refusal names `what` and its size (`shown`, when the framing is not counted)."""
        shown = size if shown is None else shown
        text = f"{shown / (KB * KB):g} MB" if shown >= KB * KB else f"{shown // KB} KB"
        return cls(size, f"{what} too large: the limit is {text}")


class BodyLimits:
    """ASGI middleware: `limits` maps (method, path) to a Limit; any other request gets `default`."""

    def __init__(self, app: ASGIApp, *, default: Limit, limits: Mapping[tuple[str, str], Limit],
                 read_timeout_s: float, min_rate: float = MIN_BODY_RATE):
        self.app, self.default, self.limits, self.read_timeout_s = app, default, dict(limits), read_timeout_s
        self.min_rate = min_rate

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.limits.get((scope["method"], scope["path"].rstrip("/")), self.default)
        declared = _content_length(scope)
        if declared is not None and declared > limit.size:
            await _refuse(send, 413, limit.refusal)
            return
        await _Guarded(self.app, scope, receive, send, limit, self.read_timeout_s, self.min_rate).run()


class _Guarded:
    """One request whose body is counted and timed; after a refusal the app sees a disconnect and
    whatever it tries to send is dropped."""

    def __init__(self, app: ASGIApp, scope: Scope, receive: Receive, send: Send, limit: Limit, timeout_s: float,
                 min_rate: float):
        self.app, self.scope, self._receive, self._send = app, scope, receive, send
        self.limit, self.timeout_s, self.min_rate = limit, timeout_s, min_rate
        self.received, self.started, self.refused, self.body_done = 0, False, False, False
        self.first_read_at: float | None = None

    async def run(self) -> None:
        try:
            await self.app(self.scope, self.receive, self.send)
        except Exception:
            if not self.refused:
                raise  # after a refusal the app only sees the client gone: that is not an error

    async def receive(self) -> Message:
        if self.refused:
            return {"type": "http.disconnect"}
        if self.body_done:
            return await self._receive()
        now = asyncio.get_running_loop().time()
        self.first_read_at = self.first_read_at or now
        stall = now + self.timeout_s  # silence counted from this read: a late read is not the client's
        # The rate bound starts a whole timeout after the stall bound could first fire: a body that
        # stops is said stopped even when a busy loop reads it late (up to a timeout late), where a
        # near tie of the two bounds would be decided by the loop's milliseconds, not by the client.
        rate = self.first_read_at + 2 * self.timeout_s + self.received / self.min_rate
        try:
            message = await asyncio.wait_for(self._receive(), max(0.0, min(stall, rate) - now))
        except asyncio.TimeoutError:
            if stall <= rate:
                return await self.refuse(408, f"the request body stopped arriving for {self.timeout_s:g} s")
            return await self.refuse(408, f"the request body arrived slower than {self.min_rate / KB:g} KB/s")
        if message["type"] == "http.request":
            self.received += len(message.get("body", b""))
            if self.received > self.limit.size:
                return await self.refuse(413, self.limit.refusal)
            self.body_done = not message.get("more_body", False)
        return message

    async def refuse(self, status: int, detail: str) -> Message:
        self.refused = True
        if not self.started:
            self.started = True
            await _refuse(self._send, status, detail)
        return {"type": "http.disconnect"}

    async def send(self, message: Message) -> None:
        if self.refused:
            return
        if message["type"] == "http.response.start":
            self.started = True
        await self._send(message)


def _content_length(scope: Scope) -> int | None:
    for name, value in scope["headers"]:
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return 1 << 62  # unreadable: as good as too large
    return None


async def _refuse(send: Send, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")]})
    await send({"type": "http.response.body", "body": body})

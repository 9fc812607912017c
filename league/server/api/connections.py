"""Connections, bounded before any request is read: how many the API holds at once (in all, and from
one client address), how long and how large a request head (its line and headers) may be.

uvicorn reads a request head for as long as the client cares to send it, of any size, and accepts
connections until accept() fails for want of file handles; so a thousand sockets that each send
half a header hold the API offline. `guarded_protocol(limits)` is uvicorn's own HTTP protocol with
three checks added (league serve runs it, through `uvicorn_protocols`):

- a connection over the bound (`max_connections`, or `max_per_client` from one address; an IPv6
  client is its /64) is answered 503 and closed at once; when all connections are taken, the one
  that has waited longest for a request head is closed instead, if one is waiting;
- a connection that has not sent a whole request head `head_timeout_s` after it opened, or after
  its last answer (keep-alive), is closed (408 if it had sent part of one);
- a head over MAX_HEAD_BYTES is answered 431 and the connection closed;
- bodies are bounded by league.server.api.limits, as before.

`raise_open_file_limit()` gives the process every file handle it may have, so that the bound,
not accept(), decides; `effective_limits` keeps the bound within them.
"""
from __future__ import annotations

import asyncio
import ipaddress
import json
import logging
import resource
import time
from collections import Counter
from dataclasses import dataclass, replace

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from league.server.core.config import Settings

log = logging.getLogger("league.server.connections")
MAX_HEAD_BYTES = 32 * 1024  # a request line and headers; browsers send 1-2 KB (nginx allows 32 KB)
RESERVED_FILES = 128  # file handles kept for the database, the store, logs and the thread pool
REFUSAL_LOG_INTERVAL_S = 10.0  # refusals are logged as counts, at most this often


@dataclass(frozen=True)
class ConnectionLimits:
    max_connections: int
    max_per_client: int  # 0: no bound per address (behind a reverse proxy every client is the proxy)
    head_timeout_s: float
    max_head_bytes: int = MAX_HEAD_BYTES


def client_address(peername) -> str | None:
    """The address a per-client bound counts: an IPv4 address, or an IPv6 /64 (what one host gets);
    None for a Unix socket."""
    if not isinstance(peername, tuple) or not peername:
        return None
    address = ipaddress.ip_address(peername[0])
    if address.version == 6 and address.ipv4_mapped is not None:
        return str(address.ipv4_mapped)
    if address.version == 6:
        return str(ipaddress.IPv6Network((address, 64), strict=False))
    return str(address)


class Admission:
    """The connections of one server: how many, from whom, and which wait for a request head."""

    def __init__(self, limits: ConnectionLimits):
        self.limits = limits
        self.open = 0
        self.per_client: Counter[str] = Counter()
        self.waiting: dict[GuardedHttpProtocol, None] = {}  # waiting for a request head, longest first
        self.refused: Counter[str] = Counter()
        self._logged_at = time.monotonic()

    def admit(self, connection: GuardedHttpProtocol) -> bool:
        address = connection.address
        if address is not None and 0 < self.limits.max_per_client <= self.per_client[address]:
            return self._refuse(f"over {self.limits.max_per_client} from {address}")
        if self.open >= self.limits.max_connections:
            if not self.waiting:
                return self._refuse(f"over {self.limits.max_connections} in all")
            next(iter(self.waiting)).drop()  # the one that has waited longest for a request head
        self.open += 1
        if address is not None:
            self.per_client[address] += 1
        return True

    def release(self, connection: GuardedHttpProtocol) -> None:
        self.open -= 1
        if connection.address is not None:
            self.per_client[connection.address] -= 1
            if not self.per_client[connection.address]:
                del self.per_client[connection.address]

    def _refuse(self, reason: str) -> bool:
        self.refused[reason] += 1
        if time.monotonic() - self._logged_at >= REFUSAL_LOG_INTERVAL_S:
            self._logged_at = time.monotonic()
            log.warning("connections refused: %s", "; ".join(f"{n} {why}" for why, n in self.refused.items()))
            self.refused.clear()
        return False


class HeadTooLarge(Exception):
    """Raised in the parser's callback to stop it."""


def plain_response(status: str, detail: str) -> bytes:
    """A whole HTTP response with a JSON detail, after which the connection closes."""
    body = json.dumps({"detail": detail}).encode()
    return (f"HTTP/1.1 {status}\r\ncontent-type: application/json\r\nconnection: close\r\n"
            f"content-length: {len(body)}\r\n\r\n").encode() + body


BUSY = plain_response("503 Service Unavailable", "too many connections: try again in a moment")


class GuardedHttpProtocol(HttpToolsProtocol):
    """uvicorn's HTTP/1.1 protocol under an Admission (see the module's docstring)."""

    admission: Admission  # set by guarded_protocol(): one per server

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.address: str | None = None
        self.admitted = False
        self.head_timer: asyncio.TimerHandle | None = None  # while a request head is awaited
        self.in_head, self.head_bytes = False, 0  # the parser is inside a head; bytes received since it began
        self.refused_head = False

    def connection_made(self, transport) -> None:
        self.address = client_address(transport.get_extra_info("peername"))
        if not self.admission.admit(self):
            self.transport = transport  # what connection_lost closes
            transport.write(BUSY)
            transport.close()
            return
        self.admitted = True
        super().connection_made(transport)
        self.await_head()

    def connection_lost(self, exc) -> None:
        self.release()
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        if self.in_head:  # the data ended inside a head (a chunk that also ended a pipelined request counts whole)
            self.head_bytes += len(data)
            if self.head_bytes > self.admission.limits.max_head_bytes:
                self.drop(self.head_too_large())

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self.in_head, self.head_bytes = True, 0

    def on_headers_complete(self) -> None:
        self.in_head = False
        self.stop_head_timer()
        if len(self.url) + sum(len(name) + len(value) + 4 for name, value in self.headers) > \
                self.admission.limits.max_head_bytes:  # a whole head in one piece
            self.refused_head = True
            raise HeadTooLarge  # the parser stops; uvicorn calls send_400_response
        super().on_headers_complete()

    def send_400_response(self, msg: str) -> None:
        if self.refused_head:
            self.drop(self.head_too_large())
        else:
            super().send_400_response(msg)

    def head_too_large(self) -> bytes:
        kb = self.admission.limits.max_head_bytes // 1024
        return plain_response("431 Request Header Fields Too Large",
                              f"request line and headers too large: the limit is {kb} KB")

    def on_response_complete(self) -> None:
        idle = not self.pipeline  # else the next request's head has arrived already
        super().on_response_complete()
        if idle and not self.transport.is_closing():
            self.await_head()

    def await_head(self) -> None:
        self.stop_head_timer()
        self.head_timer = self.loop.call_later(self.admission.limits.head_timeout_s, self.head_timed_out)
        self.admission.waiting[self] = None

    def stop_head_timer(self) -> None:
        if self.head_timer is not None:
            self.head_timer.cancel()
            self.head_timer = None
        self.admission.waiting.pop(self, None)

    def head_timed_out(self) -> None:
        self.head_timer = None
        detail = f"the request head did not arrive within {self.admission.limits.head_timeout_s:g} s"
        self.drop(plain_response("408 Request Timeout", detail) if self.in_head else b"")

    def drop(self, answer: bytes = b"") -> None:
        """Close the connection now (after `answer`, if any); it no longer counts."""
        self.release()
        if not self.transport.is_closing():
            if answer:
                self.transport.write(answer)
            self.transport.close()

    def release(self) -> None:
        self.stop_head_timer()
        if self.admitted:
            self.admitted = False
            self.admission.release(self)


def guarded_protocol(limits: ConnectionLimits) -> type[GuardedHttpProtocol]:
    """The protocol class to give uvicorn (`http=`): every connection of one server shares its Admission."""
    return type("GuardedHttpProtocol", (GuardedHttpProtocol,), {"admission": Admission(limits)})


def uvicorn_protocols(limits: ConnectionLimits) -> dict:
    """uvicorn's `http` and `ws` options: the guarded protocol, and no WebSocket protocol. The API has
    no WebSocket route, and a connection upgraded to one would leave the Admission uncounted."""
    return {"http": guarded_protocol(limits), "ws": "none"}


def connection_limits(settings: Settings) -> ConnectionLimits:
    """The settings' limits, the connections within the open-file limit (raised first); logged."""
    limits = effective_limits(ConnectionLimits(settings.max_connections, settings.max_connections_per_client,
                                               settings.request_head_timeout_s), raise_open_file_limit())
    per_client = limits.max_per_client or "no bound"
    log.info("connections: at most %d (%s per client address); request heads within %g s, %d KB",
             limits.max_connections, per_client, limits.head_timeout_s, limits.max_head_bytes // 1024)
    return limits


def raise_open_file_limit() -> int:
    """Raise this process's soft limit of open files to its hard limit (logged); returns the limit."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < hard != resource.RLIM_INFINITY:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
        log.info("open files: the soft limit was raised from %d to the hard limit, %d", soft, hard)
        soft = hard
    return soft


def effective_limits(limits: ConnectionLimits, open_files: int) -> ConnectionLimits:
    """`limits` with max_connections within the open-file limit (RESERVED_FILES kept for the rest)."""
    allowed = max(1, open_files - RESERVED_FILES)
    if limits.max_connections <= allowed:
        return limits
    log.warning("connections: at most %d, not %d: the open-file limit is %d (raise it: ulimit -n, or "
                "LimitNOFILE= in a systemd unit)", allowed, limits.max_connections, open_files)
    return replace(limits, max_connections=allowed)

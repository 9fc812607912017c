"""The connection guard (league/server/api/connections.py) on a real socket: a real uvicorn server
with the guard, in a thread, in front of a tiny ASGI app, and the raw-socket clients that speak to
it (test_connections.py, test_limits.py)."""
from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time

import uvicorn

from league.server.api.connections import ConnectionLimits, uvicorn_protocols


async def app(scope, receive, send):
    """200 "ok"; /slow holds its answer for half a second (a connection busy with a request)."""
    if scope["type"] != "http":
        return
    if scope["path"] == "/slow":
        await asyncio.sleep(0.5)
    await send({"type": "http.response.start", "status": 200, "headers": [(b"content-type", b"text/plain")]})
    await send({"type": "http.response.body", "body": b"ok"})


@contextlib.contextmanager
def guarded_server(asgi_app=app, **limits):
    """A uvicorn server of `asgi_app` with the guard of `limits`, as league serve runs it; yields its
    (host, port)."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    config = uvicorn.Config(asgi_app, **uvicorn_protocols(ConnectionLimits(**limits)), lifespan="off",
                            log_level="warning", timeout_keep_alive=30)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [listener]}, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.01)
    try:
        yield listener.getsockname()
    finally:
        server.should_exit = True
        thread.join(10)
        listener.close()


def connect(address, source: str = "127.0.0.1") -> socket.socket:
    sock = socket.create_connection(address, timeout=10, source_address=(source, 0))
    return sock


def read_all(sock: socket.socket) -> bytes:
    """What the server sends until it closes the connection."""
    data = b""
    while chunk := sock.recv(65536):
        data += chunk
    return data


def status_line(answer: bytes) -> str:
    return answer.split(b"\r\n", 1)[0].decode()

"""Request bodies are bounded before anything reads them: a declared length over a route's limit is
refused at once, a streamed body is cut at the limit, both with a JSON 413, before authentication;
multipart bodies are read only once the token is accepted; a body that trickles in is refused (408);
an answer streamed after the body is not timed. A stalled body on a running `league serve`:
tests/system/api/test_limits.py."""
from __future__ import annotations

import asyncio
import time

import pytest
from starlette.requests import Request
from starlette.responses import StreamingResponse

from league.server.api.limits import KB, BodyLimits, Limit

from .guarded_servers import connect, guarded_server, read_all, status_line

HUGE = 75 * 1024 * 1024


def test_a_huge_declared_body_is_refused_unread_and_before_authentication(app_league):
    with app_league.client() as anonymous:  # no token at all: the size is checked first
        response = anonymous.post("/api/races", content=b"{}", headers={"Content-Length": str(HUGE),
                                                                         "Content-Type": "application/json"})
    assert response.status_code == 413
    assert response.json() == {"detail": "request body too large: the limit is 64 KB"}


def test_a_streamed_body_is_cut_at_the_limit(app_league):
    sent = []

    def chunks():
        for _ in range(64):  # 4 MB in 64 KB chunks, no Content-Length
            sent.append(1)
            yield b" " * 65536

    with app_league.client() as anonymous:
        response = anonymous.post("/api/races", content=chunks(), headers={"Content-Type": "application/json"})
    assert response.status_code == 413
    assert response.json() == {"detail": "request body too large: the limit is 64 KB"}


@pytest.mark.parametrize("path, limit", [("/api/submissions", "file too large: the limit is 5 MB"),
                                         ("/api/users/roster", "roster too large: the limit is 1 MB")])
def test_multipart_routes_have_their_own_limit_said_in_json(app_league, path, limit):
    with app_league.client(app_league.instructor_token) as instructor:
        response = instructor.post(path, files={"file": ("big.onnx", b"\0" * (6 * 1024 * 1024))})
    assert response.status_code == 413
    assert response.json() == {"detail": limit}


@pytest.mark.parametrize("path", ["/api/submissions", "/api/users/roster"])
def test_a_multipart_body_is_not_read_without_a_token(app_league, path):
    """Garbage that would fail to parse: a 401, so the body was never parsed (nor spooled)."""
    with app_league.client() as anonymous:
        response = anonymous.post(path, content=b"--x\r\nnot a form at all", headers={
            "Content-Type": "multipart/form-data; boundary=x"})
    assert response.status_code == 401
    assert response.json() == {"detail": "missing token: send the header Authorization: Bearer TOKEN"}


async def read_then_stream(scope, receive, send):
    """Reads the whole body, then streams an answer for 1.5 s (Starlette listens for the client
    leaving meanwhile, through receive)."""
    body = await Request(scope, receive).body()

    async def pieces():
        for _ in range(3):
            await asyncio.sleep(0.5)
            yield b"%d " % len(body)

    await StreamingResponse(pieces())(scope, receive, send)


def limited(read_timeout_s: float, min_rate: float):
    return BodyLimits(read_then_stream, default=Limit.of(64 * KB), limits={}, read_timeout_s=read_timeout_s,
                      min_rate=min_rate)


def test_a_body_that_trickles_in_is_refused_once_under_the_minimum_rate():
    """Never stalled for the read timeout, but 100 bytes a second against at least 1 KB/s past it."""
    with guarded_server(limited(read_timeout_s=1, min_rate=1024), max_connections=10, max_per_client=0,
                        head_timeout_s=30) as address:
        with connect(address) as sock:
            sock.sendall(b"POST / HTTP/1.1\r\nHost: league\r\nContent-Length: 10000\r\n\r\n")
            answer = b""
            for _ in range(100):  # 10 s at most, 100 bytes every 0.1 s
                sock.sendall(b"x" * 10)
                time.sleep(0.1)
                sock.settimeout(0.001)
                try:
                    answer = read_all(sock)
                    break
                except (TimeoutError, BlockingIOError):
                    sock.settimeout(10)
    assert status_line(answer) == "HTTP/1.1 408 Request Timeout"
    assert answer.endswith(b'{"detail": "the request body arrived slower than 1 KB/s"}')


async def read_busily(scope, receive, send):
    """Reads the first chunk, then blocks its event loop for 50 ms (a busy server) before reading on."""
    await receive()
    time.sleep(0.05)
    while (await receive())["type"] == "http.request":
        pass


async def read_while_the_loop_blocks(scope, receive, send):
    """Its event loop is blocked for 50 ms (a busy server) while its first chunk is being read."""
    asyncio.get_running_loop().call_soon(time.sleep, 0.05)
    while (await receive())["type"] == "http.request":
        pass


@pytest.mark.parametrize("app", [read_busily, read_while_the_loop_blocks])
def test_a_body_that_stops_is_said_stopped_even_when_a_busy_loop_reads_it_late(app):
    """A read 50 ms late, after the first chunk or while it is taken (CI's failure on a loaded
    machine, with a few milliseconds): the rate bound (19 bytes at 8 KB/s) must not come first,
    for what the client did is that it sent nothing for the whole timeout."""
    app = BodyLimits(app, default=Limit.of(64 * KB), limits={}, read_timeout_s=1, min_rate=8 * KB)
    with guarded_server(app, max_connections=10, max_per_client=0, head_timeout_s=30) as address:
        with connect(address) as sock:
            sock.sendall(b"POST / HTTP/1.1\r\nHost: league\r\nContent-Length: 1000\r\n\r\n{\"submission_ids\": ")
            answer = read_all(sock)
    assert status_line(answer) == "HTTP/1.1 408 Request Timeout"
    assert answer.endswith(b'{"detail": "the request body stopped arriving for 1 s"}'), answer


def test_an_answer_streamed_after_the_body_is_not_cut_by_the_body_timeout():
    with guarded_server(limited(read_timeout_s=0.5, min_rate=1024), max_connections=10, max_per_client=0,
                        head_timeout_s=30) as address:
        with connect(address) as sock:
            sock.sendall(b"POST / HTTP/1.1\r\nHost: league\r\nConnection: close\r\nContent-Length: 3\r\n\r\nabc")
            answer = read_all(sock)
    assert status_line(answer) == "HTTP/1.1 200 OK"
    assert answer.count(b"\r\n3 \r\n") == 3 and answer.endswith(b"\r\n0\r\n\r\n")  # three chunks, then the end

"""Request bodies on a running `league serve`: a body that stops arriving is refused (408) and the
API goes on. The limits in process: tests/server/api/test_limits.py."""
from __future__ import annotations

import socket
import time

from ...server.backends import fresh_backend
from ..servers import make_server


def test_a_body_that_stops_arriving_is_refused_and_the_api_goes_on(tmp_path):
    """A real server and a client that sends half a body, then nothing: a 408 after the timeout."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_REQUEST_BODY_TIMEOUT_S="1", LEAGUE_BOOTSTRAP="false")
        server.start_api(embedded_worker=False)
        try:
            with socket.create_connection(("127.0.0.1", server.port), timeout=30) as client:
                client.sendall(b"POST /api/races HTTP/1.1\r\nHost: test\r\nContent-Type: application/json\r\n"
                               b"Content-Length: 1000\r\n\r\n{\"submission_ids\": ")
                started = time.monotonic()
                answer = b"".join(iter(lambda: client.recv(4096), b"")).decode()  # until the server closes
                waited = time.monotonic() - started
            with server.client() as anonymous:
                assert anonymous.get("/api/health").json()["status"] == "degraded"  # it answers (no worker)
        finally:
            server.stop_all()
    assert answer.startswith("HTTP/1.1 408"), answer
    assert answer.endswith('{"detail": "the request body stopped arriving for 1 s"}'), answer
    assert waited < 30  # it was the server that gave up, not our socket

"""The connection guard (league/server/api/connections.py): uvicorn's own HTTP protocol with bounds on
connections (in all, per client address), on the time and size of a request head. Each test runs a
real uvicorn server with the guard on a real socket, in a thread, in front of a tiny ASGI app (guarded_servers.py);
the clients are raw sockets, some from another loopback address (127.0.0.2) to be another client.
The whole league under attack, run by an ordinary user: test_hostile_clients.py."""
from __future__ import annotations

import subprocess
import sys
import time

import pytest

from league.server.api.connections import ConnectionLimits, client_address, effective_limits

from .guarded_servers import connect, guarded_server, read_all, status_line

OTHER_CLIENT = "127.0.0.2"  # every 127.x.y.z is this host's: another client address without a network


def request(address, path: str = "/", source: str = "127.0.0.1") -> bytes:
    with connect(address, source) as sock:
        sock.sendall(f"GET {path} HTTP/1.1\r\nHost: league\r\nConnection: close\r\n\r\n".encode())
        return read_all(sock)


HALF_A_HEAD = b"GET / HTTP/1.1\r\nHost: league\r\nX-Wait: "


def test_a_connection_without_a_whole_head_in_time_is_closed():
    """Silent: closed without a word; half a head: a 408 that says why. Both after the timeout, not before."""
    with guarded_server(max_connections=10, max_per_client=0, head_timeout_s=0.5) as address:
        silent, partial = connect(address), connect(address)
        partial.sendall(HALF_A_HEAD)
        started = time.monotonic()
        assert read_all(silent) == b""
        answer = read_all(partial)
        waited = time.monotonic() - started
        assert status_line(answer) == "HTTP/1.1 408 Request Timeout"
        assert answer.endswith(b'{"detail": "the request head did not arrive within 0.5 s"}')
        assert waited >= 0.4
        assert status_line(request(address)) == "HTTP/1.1 200 OK"


def test_the_head_timeout_starts_again_after_each_answer():
    """Keep-alive: a connection answered once must not then hold the server by sending half a head."""
    with guarded_server(max_connections=10, max_per_client=0, head_timeout_s=0.5) as address:
        with connect(address) as sock:
            for _ in range(3):  # whole requests, each well within the timeout of the one before
                sock.sendall(b"GET / HTTP/1.1\r\nHost: league\r\n\r\n")
                assert sock.recv(65536).startswith(b"HTTP/1.1 200 OK")
                time.sleep(0.3)
            sock.sendall(HALF_A_HEAD)
            assert status_line(read_all(sock)) == "HTTP/1.1 408 Request Timeout"


def test_a_head_over_the_limit_is_refused_at_once():
    with guarded_server(max_connections=10, max_per_client=0, head_timeout_s=30, max_head_bytes=4096) as address:
        with connect(address) as sock:
            sock.sendall(HALF_A_HEAD + b"x" * 8192)
            answer = read_all(sock)  # long before the 30 s timeout
        assert status_line(answer) == "HTTP/1.1 431 Request Header Fields Too Large"
        assert answer.endswith(b'{"detail": "request line and headers too large: the limit is 4 KB"}')
        with connect(address) as sock:  # sent whole, in one piece
            sock.sendall(b"GET / HTTP/1.1\r\nHost: league\r\nX-Pad: " + b"x" * 8192 + b"\r\n\r\n")
            assert status_line(read_all(sock)) == "HTTP/1.1 431 Request Header Fields Too Large"
        with connect(address) as sock:  # a large head within the limit is fine
            sock.sendall(b"GET / HTTP/1.1\r\nHost: league\r\nConnection: close\r\nX-Pad: " + b"x" * 3000 + b"\r\n\r\n")
            assert status_line(read_all(sock)) == "HTTP/1.1 200 OK"


def test_one_client_gets_its_share_and_is_refused_at_once_beyond_it():
    with guarded_server(max_connections=50, max_per_client=5, head_timeout_s=30) as address:
        held = [connect(address) for _ in range(5)]
        with connect(address) as refused:  # answered at once (a timed-out one gets no 503), before it sends anything
            answer = read_all(refused)
        assert status_line(answer) == "HTTP/1.1 503 Service Unavailable"
        assert answer.endswith(b'{"detail": "too many connections: try again in a moment"}')
        assert status_line(request(address, source=OTHER_CLIENT)) == "HTTP/1.1 200 OK"
        held.pop().close()  # a place freed is taken again
        time.sleep(0.2)
        assert status_line(request(address)) == "HTTP/1.1 200 OK"
        for sock in held:
            sock.close()


def test_when_every_connection_is_taken_the_one_waiting_longest_for_a_head_makes_room():
    with guarded_server(max_connections=4, max_per_client=0, head_timeout_s=30) as address:
        waiting = [connect(address) for _ in range(4)]
        time.sleep(0.2)
        assert status_line(request(address)) == "HTTP/1.1 200 OK"
        waiting[0].settimeout(5)
        assert waiting[0].recv(1) == b""  # the oldest made room
        for sock in waiting[1:]:
            sock.close()
        time.sleep(0.2)

        busy = [connect(address) for _ in range(4)]  # every connection inside a request: none to close
        for sock in busy:
            sock.sendall(b"GET /slow HTTP/1.1\r\nHost: league\r\n\r\n")
        time.sleep(0.1)
        with connect(address) as refused:  # answered at once, before it sends anything
            assert status_line(read_all(refused)) == "HTTP/1.1 503 Service Unavailable"
        for sock in busy:
            assert sock.recv(65536).startswith(b"HTTP/1.1 200 OK")
            sock.close()


def test_an_upgrade_to_websocket_is_plain_http_and_keeps_its_place_counted():
    with guarded_server(max_connections=2, max_per_client=0, head_timeout_s=30) as address:
        for _ in range(5):  # had uvicorn switched them to its WebSocket protocol, none would be released
            with connect(address) as sock:
                sock.sendall(b"GET / HTTP/1.1\r\nHost: league\r\nConnection: close, Upgrade\r\nUpgrade: websocket\r\n"
                             b"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n")
                assert status_line(read_all(sock)) == "HTTP/1.1 200 OK"
        time.sleep(0.2)
        held = [connect(address) for _ in range(2)]
        for sock in held:
            sock.sendall(b"GET / HTTP/1.1\r\nHost: league\r\n\r\n")
            assert sock.recv(65536).startswith(b"HTTP/1.1 200 OK")
            sock.close()


@pytest.mark.parametrize("peer, counted", [
    (("192.0.2.7", 5000), "192.0.2.7"),
    (("2001:db8:1:2:3:4:5:6", 5000, 0, 0), "2001:db8:1:2::/64"),  # one host's /64 is one client
    (("2001:db8:1:2:ffff::1", 5000, 0, 0), "2001:db8:1:2::/64"),
    (("::ffff:192.0.2.7", 5000, 0, 0), "192.0.2.7"),
    ("/run/league.sock", None),
])
def test_the_address_a_client_is_counted_by(peer, counted):
    assert client_address(peer) == counted


def test_the_bound_stays_within_the_open_file_limit():
    limits = ConnectionLimits(max_connections=5000, max_per_client=100, head_timeout_s=10)
    assert effective_limits(limits, 1024).max_connections == 1024 - 128
    assert effective_limits(limits, 65536) == limits


def test_the_soft_open_file_limit_is_raised_to_the_hard_limit():
    probe = ("import resource; from league.server.api.connections import raise_open_file_limit; "
             "print(raise_open_file_limit(), *resource.getrlimit(resource.RLIMIT_NOFILE))")
    done = subprocess.run(["prlimit", "--nofile=256:2048", sys.executable, "-c", probe], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["2048", "2048", "2048"]

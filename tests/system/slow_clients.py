"""Half-open connections, as issue 22's attacker made them: each sends part of a request head, then
nothing. A program, run on another host (a network namespace) so that the server sees another client:

    python -m tests.system.slow_clients HOST PORT COUNT WATCH_S

opens COUNT such connections one after the other, prints "holding" once they are all open, then
watches each until the server ends it (at most WATCH_S seconds) and prints one JSON line: per
connection, how it ended ("503", "408", another status, "closed" without an answer, "reset", or
"open" when it was still open at the end) and when, in seconds after it was opened.
"""
from __future__ import annotations

import json
import resource
import selectors
import socket
import sys
import time

HALF_A_HEAD = b"GET /api/health HTTP/1.1\r\nHost: league\r\nX-Wait: "


def open_connections(address: tuple[str, int], count: int) -> list[tuple[socket.socket, float]]:
    opened = []
    for _ in range(count):
        sock = socket.create_connection(address, timeout=30)
        started = time.monotonic()
        try:
            sock.sendall(HALF_A_HEAD)
        except OSError:  # refused at once: answered and closed before our bytes arrived
            pass
        sock.setblocking(False)
        opened.append((sock, started))
    return opened


def watch(opened: list[tuple[socket.socket, float]], watch_s: float) -> list[dict]:
    selector = selectors.DefaultSelector()
    ends: list[dict | None] = [None] * len(opened)
    received = [b""] * len(opened)
    for k, (sock, _) in enumerate(opened):
        selector.register(sock, selectors.EVENT_READ, k)
    deadline = time.monotonic() + watch_s
    while selector.get_map() and time.monotonic() < deadline:
        for key, _ in selector.select(timeout=0.1):
            k = key.data
            try:
                chunk = key.fileobj.recv(65536)
            except BlockingIOError:
                continue
            except OSError:
                chunk, received[k] = b"", b"reset"
            received[k] += chunk
            if not chunk:
                selector.unregister(key.fileobj)
                ends[k] = {"end": outcome(received[k]), "after_s": round(time.monotonic() - opened[k][1], 3)}
    return [end or {"end": "open", "after_s": None} for end in ends]


def outcome(received: bytes) -> str:
    if received == b"reset" or not received:
        return "reset" if received else "closed"
    return received.split(b" ", 2)[1].decode(errors="replace")  # HTTP/1.1 503 ...


def main(host: str, port: str, count: str, watch_s: str) -> None:
    hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # the attacker's own handles are not the test
    opened = open_connections((host, int(port)), int(count))
    print("holding", flush=True)
    print(json.dumps(watch(opened, float(watch_s))), flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:])

"""The public-answer cache: one computation per period and key, stale answers served while a
single refresh runs, nothing kept with a period of 0."""
from __future__ import annotations

import threading
import time

from league.server.api.cache import ResponseCache


class Clock:
    """Time that moves only when told to."""

    def __init__(self):
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


class Counter:
    def __init__(self, delay: float = 0.0):
        self.calls, self.delay = 0, delay
        self._lock = threading.Lock()

    def __call__(self) -> bytes:
        time.sleep(self.delay)
        with self._lock:
            self.calls += 1
            return str(self.calls).encode()


def test_concurrent_misses_compute_once():
    cache, compute = ResponseCache(ttl_s=60), Counter(delay=0.2)
    bodies = []
    threads = [threading.Thread(target=lambda: bodies.append(cache.compute("k", compute))) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert compute.calls == 1 and bodies == [b"1"] * 8
    assert cache._gates == {}  # no lock kept per key: any page number may be asked for
    assert cache.lookup("k") == (b"1", True)
    assert cache.lookup("other") == (None, False)


def test_a_stale_answer_is_served_while_one_refresh_runs():
    clock = Clock()
    cache, compute = ResponseCache(ttl_s=2, clock=clock), Counter()
    cache.compute("k", compute)
    clock.now += 1.9
    assert cache.lookup("k") == (b"1", True)
    clock.now += 0.2
    assert cache.lookup("k") == (b"1", False)
    assert cache.claim_refresh("k") and not cache.claim_refresh("k")  # one refresher only
    cache.refresh("k", compute)
    assert cache.lookup("k") == (b"2", True) and cache.claim_refresh("k")


def test_a_failed_refresh_keeps_the_stale_answer():
    clock = Clock()
    cache = ResponseCache(ttl_s=2, clock=clock)
    cache.compute("k", lambda: b"old")
    clock.now += 3

    def broken() -> bytes:
        raise RuntimeError("database down")

    assert cache.claim_refresh("k")
    cache.refresh("k", broken)
    assert cache.lookup("k") == (b"old", False) and cache.claim_refresh("k")


def test_a_period_of_zero_keeps_nothing_fresh():
    cache, compute = ResponseCache(ttl_s=0), Counter()
    assert [cache.compute("k", compute) for _ in range(3)] == [b"1", b"2", b"3"]

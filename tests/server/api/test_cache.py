"""The public-answer cache: one computation per period, key and state stamp, stale answers served
while a single refresh runs but never past their maximum age, a new stamp computed at once,
nothing kept with a period of 0. (Over HTTP, with the database's stamp: test_leaderboard.py.)"""
from __future__ import annotations

import threading
import time

import pytest

from league.server.api.cache import ENTRY_OVERHEAD, ResponseCache


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
    assert compute.calls == 1 and [entry.body for entry in bodies] == [b"1"] * 8
    assert cache._gates == {}  # no lock kept per key: any page number may be asked for
    assert body(cache.lookup("k")) == (b"1", True)
    assert cache.lookup("other") == (None, False)


def body(found) -> tuple[bytes | None, bool]:
    entry, fresh = found
    return (entry.body if entry else None), fresh


def test_a_stale_answer_is_served_while_one_refresh_runs():
    clock = Clock()
    cache, compute = ResponseCache(ttl_s=2, max_age_s=5, clock=clock), Counter()
    cache.compute("k", compute)
    clock.now += 1.9
    assert body(cache.lookup("k")) == (b"1", True)
    clock.now += 0.2
    assert body(cache.lookup("k")) == (b"1", False)
    assert cache.claim_refresh("k") and not cache.claim_refresh("k")  # one refresher only
    cache.refresh("k", compute)
    assert body(cache.lookup("k")) == (b"2", True) and cache.claim_refresh("k")


def test_no_answer_is_served_past_its_maximum_age():
    """After a quiet period the first reader gets a new answer, not the one kept from before."""
    clock = Clock()
    cache, compute = ResponseCache(ttl_s=2, max_age_s=5, clock=clock), Counter()
    cache.compute("k", compute)
    clock.now += 4.9
    assert body(cache.lookup("k")) == (b"1", False)  # stale, servable while it is refreshed
    clock.now += 0.1
    assert cache.lookup("k") == (None, False)
    assert cache.compute("k", compute).body == b"2"
    assert ResponseCache(ttl_s=2, max_age_s=1).max_age_s == 2  # never below the fresh period


def test_an_answer_of_another_state_stamp_is_not_served():
    """A finished evaluation or heat changes the stamp: the next request computes, however fresh the kept answer."""
    cache, compute = ResponseCache(ttl_s=60, max_age_s=60, clock=Clock()), Counter()
    first = cache.compute("k", compute, stamp=(1,))
    assert body(cache.lookup("k", (1,))) == (b"1", True)
    assert cache.lookup("k", (2,)) == (None, False)
    second = cache.compute("k", compute, stamp=(2,))
    assert (second.body, second.stamp) == (b"2", (2,)) and second.etag != first.etag
    assert cache.lookup("k", (1,)) == (None, False)  # one entry per key: the newest stamp's


def test_a_failed_refresh_keeps_the_stale_answer_until_its_maximum_age():
    clock = Clock()
    cache = ResponseCache(ttl_s=2, max_age_s=5, clock=clock)
    cache.compute("k", lambda: b"old")
    clock.now += 3

    def broken() -> bytes:
        raise RuntimeError("database down")

    assert cache.claim_refresh("k")
    cache.refresh("k", broken)
    assert body(cache.lookup("k")) == (b"old", False) and cache.claim_refresh("k")
    clock.now += 2
    assert cache.lookup("k") == (None, False)


def test_a_period_of_zero_keeps_nothing_fresh():
    cache, compute = ResponseCache(ttl_s=0), Counter()
    assert [cache.compute("k", compute).body for _ in range(3)] == [b"1", b"2", b"3"]
    assert cache.lookup("k") == (None, False)


def test_a_failed_computation_keeps_nothing_per_key():
    """Any id may be asked for (standings of a championship that does not exist: a 404 raised while
    computing): nothing stays behind for it, or memory would grow with every id."""
    cache = ResponseCache(ttl_s=60)

    def missing() -> bytes:
        raise LookupError("championship 123 does not exist")

    for key in range(100):
        with pytest.raises(LookupError):
            cache.compute(("standings", key), missing)
    assert cache._gates == {} and len(cache._entries) == 0


def test_kept_answers_are_bounded_in_bytes_least_recently_used_out_first():
    cache = ResponseCache(ttl_s=60, max_bytes=10 * (1000 + ENTRY_OVERHEAD))
    for page in range(25):
        cache.compute(("leaderboard", page), lambda: b"x" * 1000)
    assert len(cache._entries) == 10 and cache._entries.currsize <= cache._entries.maxsize
    assert cache.lookup(("leaderboard", 24))[0] is not None and cache.lookup(("leaderboard", 0))[0] is None
    huge = cache.compute("huge", lambda: b"x" * 20_000)  # larger than the whole cache: served, not kept
    assert huge.body == b"x" * 20_000 and cache.lookup("huge") == (None, False)

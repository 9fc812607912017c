"""Public answers served from memory, so a class refreshing the leaderboard does not load the
database: an answer older than `ttl_s` is still served while one background thread computes its
successor (stale-while-revalidate), so no request waits for a recomputation but the very first."""
from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable, Hashable

from cachetools import LRUCache
from fastapi import Request, Response
from fastapi.concurrency import run_in_threadpool

log = logging.getLogger("league.server.cache")


class ResponseCache:
    def __init__(self, ttl_s: float, maxsize: int = 4096, clock: Callable[[], float] = time.monotonic):
        self.ttl_s, self.clock = ttl_s, clock
        self._entries: LRUCache = LRUCache(maxsize)  # key -> (computed at, body)
        self._lock = threading.Lock()
        self._gates: dict[Hashable, threading.Lock] = {}  # one computation per key at a time
        self._refreshing: set[Hashable] = set()

    def lookup(self, key: Hashable) -> tuple[bytes | None, bool]:
        """(the kept body or None, whether it is fresh)."""
        with self._lock:
            entry = self._entries.get(key)
        if entry is None:
            return None, False
        return entry[1], self.clock() - entry[0] < self.ttl_s

    def compute(self, key: Hashable, compute: Callable[[], bytes]) -> bytes:
        """`compute()`'s body, kept; callers arriving meanwhile wait for it instead of computing too."""
        with self._lock:
            gate = self._gates.setdefault(key, threading.Lock())
        with gate:
            body, fresh = self.lookup(key)
            if fresh:
                return body
            started = self.clock()
            body = compute()
            with self._lock:
                self._entries[key] = (started, body)
                self._gates.pop(key, None)  # callers waiting hold it; keys (e.g. any page number) must not pile up
            return body

    def claim_refresh(self, key: Hashable) -> bool:
        """True for the one caller that should refresh a stale key."""
        with self._lock:
            if key in self._refreshing:
                return False
            self._refreshing.add(key)
            return True

    def refresh(self, key: Hashable, compute: Callable[[], bytes]) -> None:
        try:
            self.compute(key, compute)
        except Exception:  # the stale answer stays; the next request after the period tries again
            log.exception("refreshing %r failed", key)
        finally:
            with self._lock:
                self._refreshing.discard(key)


async def cached_json(request: Request, key: Hashable, compute: Callable[[], bytes]) -> Response:
    """A JSON response from the app's cache (computed in the thread pool on the first request)."""
    cache: ResponseCache = request.app.state.cache
    body, fresh = cache.lookup(key)
    if body is None or cache.ttl_s <= 0:
        body = await run_in_threadpool(cache.compute, key, compute)
    elif not fresh and cache.claim_refresh(key):
        asyncio.get_running_loop().run_in_executor(None, cache.refresh, key, compute)
    return Response(body, media_type="application/json",
                    headers={"Cache-Control": f"public, max-age={max(int(cache.ttl_s), 0)}"})

"""Public answers served from memory, so a class refreshing the leaderboard does not load the
database, yet never older than a bound; and ETags, so pollers get 304 Not Modified.

Each kept answer carries the database's state stamp it was computed under
(crud.public_state_stamp, a read of a few indexes on every request): once an evaluation or a
heat is done the stamp changes, and the next request computes the new answer (uploads and
validations, most of a deadline rush's changes, show nothing here and leave it). Under an
unchanged stamp an answer is fresh for `ttl_s`; until `max_age_s` it is still served while one
background thread computes its successor (stale-while-revalidate); older, it is computed again
before it is served. So a change the stamp reads is visible on the next request, any other within
max_age_s (a public flag; a job whose finish time is older than one already read: stamped by a
worker whose clock is behind, or committed just after a job that finished later).
"""
from __future__ import annotations

import asyncio
import hashlib
import logging
import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass

from cachetools import LRUCache
from fastapi import Request, Response
from fastapi.concurrency import run_in_threadpool

from league.server.db import crud

log = logging.getLogger("league.server.cache")
PUBLIC = "public, no-cache"  # clients and proxies may keep answers, but ask (If-None-Match) before reusing one
PRIVATE = "private, no-cache"  # the browser keeps it (not a proxy: it is the viewer's), and asks before reusing it
MAX_BYTES = 16 * 1024 * 1024  # kept answers' bodies and ENTRY_OVERHEAD each: what any page number may cost
ENTRY_OVERHEAD = 512  # bytes a kept answer costs besides its body (key, Entry, ETag, the LRU's links)


@dataclass(frozen=True)
class Entry:
    stamp: Hashable
    computed_at: float
    body: bytes
    etag: str


class ResponseCache:
    def __init__(self, ttl_s: float, max_age_s: float | None = None, max_bytes: int = MAX_BYTES,
                 clock: Callable[[], float] = time.monotonic):
        self.ttl_s, self.clock = ttl_s, clock
        self.max_age_s = max(ttl_s, ttl_s if max_age_s is None else max_age_s)
        # key -> Entry (only the newest stamp's), least recently used out first past max_bytes
        self._entries: LRUCache = LRUCache(max_bytes, getsizeof=entry_size)
        self._lock = threading.Lock()
        self._gates: dict[Hashable, threading.Lock] = {}  # one computation per key at a time
        self._refreshing: set[Hashable] = set()

    def lookup(self, key: Hashable, stamp: Hashable = None) -> tuple[Entry | None, bool]:
        """(the kept entry if it may be served under `stamp`, whether it is fresh)."""
        with self._lock:
            entry = self._entries.get(key)
        if entry is None or entry.stamp != stamp:
            return None, False
        age = self.clock() - entry.computed_at
        if age >= self.max_age_s:
            return None, False
        return entry, age < self.ttl_s

    def compute(self, key: Hashable, compute: Callable[[], bytes], stamp: Hashable = None) -> Entry:
        """`compute()`'s body, kept; callers arriving meanwhile wait for it instead of computing too."""
        with self._lock:
            gate = self._gates.setdefault(key, threading.Lock())
        with gate:
            try:
                entry, fresh = self.lookup(key, stamp)
                if fresh:
                    return entry
                started = self.clock()
                body = compute()
                entry = Entry(stamp, started, body, body_etag(body))
                with self._lock:
                    if entry_size(entry) <= self._entries.maxsize:
                        self._entries[key] = entry
                return entry
            finally:  # callers waiting hold the gate; keys (any page number, any id) must not pile up, failed or not
                with self._lock:
                    self._gates.pop(key, None)

    def claim_refresh(self, key: Hashable) -> bool:
        """True for the one caller that should refresh a stale key."""
        with self._lock:
            if key in self._refreshing:
                return False
            self._refreshing.add(key)
            return True

    def refresh(self, key: Hashable, compute: Callable[[], bytes], stamp: Hashable = None) -> None:
        try:
            self.compute(key, compute, stamp)
        except Exception:  # the stale answer stays until max_age_s; the next request after the period tries again
            log.exception("refreshing %r failed", key)
        finally:
            with self._lock:
                self._refreshing.discard(key)


def entry_size(entry: Entry) -> int:
    return len(entry.body) + ENTRY_OVERHEAD


def read_stamp(sessions) -> tuple:
    with sessions() as session:
        return crud.public_state_stamp(session)


async def cached_json(request: Request, cache: ResponseCache, sessions, key: Hashable, compute: Callable[[], bytes],
                      cache_control: str = PUBLIC) -> Response:
    """A JSON response from the app's cache (computed in the thread pool when none may be served),
    under the database state stamp read from `sessions`; `key` says whose answer it is (the course,
    real or public names)."""
    stamp = await run_in_threadpool(read_stamp, sessions)
    entry, fresh = cache.lookup(key, stamp)
    if entry is None:
        entry = await run_in_threadpool(cache.compute, key, compute, stamp)
    elif not fresh and cache.claim_refresh(key):
        asyncio.get_running_loop().run_in_executor(None, cache.refresh, key, compute, stamp)
    return etag_response(request, entry.body, cache_control, entry.etag)


def body_etag(body: bytes) -> str:
    return f'"{hashlib.blake2b(body, digest_size=12).hexdigest()}"'


def etag_response(request: Request, body: bytes, cache_control: str, etag: str | None = None) -> Response:
    """`body` as JSON with its ETag, or 304 Not Modified when the client holds it already."""
    etag = etag or body_etag(body)
    headers = {"ETag": etag, "Cache-Control": cache_control}
    held = held_etags(request)
    if etag in held or "*" in held:
        return Response(status_code=304, headers=headers)
    return Response(body, media_type="application/json", headers=headers)


def held_etags(request: Request) -> set[str]:
    """The entity tags of If-None-Match (a comma-separated list; weak ones compare as strong, RFC 9110 13.1.2)."""
    header = request.headers.get("if-none-match", "")
    return {tag.strip().removeprefix("W/") for tag in header.split(",") if tag.strip()}

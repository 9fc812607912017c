"""The app's start (league/server/app.py's lifespan)."""
from __future__ import annotations

import gc

from .in_process import in_process_league


def test_the_startups_objects_are_frozen_out_of_the_collectors_sight(tmp_path):
    """A full collection in the middle of answers would walk every module, route and schema of the app
    (bench_server (d): the status answers' p99 halves without it)."""
    gc.unfreeze()
    assert gc.get_freeze_count() == 0
    with in_process_league("sqlite", tmp_path) as league:
        with league.client() as client:
            assert client.get("/api/health").status_code in (200, 503)
        assert gc.get_freeze_count() > 10_000

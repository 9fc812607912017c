"""A worker's sign of life on its own machine, for `league worker --check` (a container's health check).

After each reaper pass that reached the database the worker touches DATA_DIR/worker.alive; the
check passes while that file is younger than STALE_PASSES reaper intervals. A worker whose
database went away, or whose process hangs, stops touching it and turns unhealthy.
"""
from __future__ import annotations

import time
from pathlib import Path

ALIVE_FILE = "worker.alive"
STALE_PASSES = 3  # passes missed before the worker counts as dead (one slow pass is not an outage)


def alive_file(data_dir: Path) -> Path:
    return Path(data_dir) / ALIVE_FILE


def beat(path: Path) -> None:
    path.touch()


def stale_reason(path: Path, interval_s: float, now: float | None = None) -> str | None:
    """Why the worker using `path` counts as dead, or None while it beats."""
    try:
        age = (time.time() if now is None else now) - path.stat().st_mtime
    except FileNotFoundError:
        return f"no worker has reached the database from here yet ({path} does not exist)"
    if age > STALE_PASSES * interval_s:
        return (f"the worker's last pass that reached the database was {age:.0f} s ago "
                f"(more than {STALE_PASSES} x LEAGUE_REAPER_INTERVAL_S = {STALE_PASSES * interval_s:g} s; {path})")
    return None

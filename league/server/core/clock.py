"""The server's clock: what upload windows, quotas and due times are decided by.

One `Clock` per league (Services.clock); tests set it (`clock.set(moment)`) instead of sleeping to a
deadline. Unset, it is the system's UTC time.
"""
from __future__ import annotations

from datetime import datetime, timezone


def utcnow() -> datetime:
    """The system's time, aware, in UTC: what every stored time is (the column defaults of db/models.py)."""
    return datetime.now(timezone.utc)


class Clock:
    def __init__(self) -> None:
        self._fixed: datetime | None = None

    def now(self) -> datetime:
        return self._fixed or utcnow()

    def set(self, moment: datetime | None) -> None:
        """Hold the clock at `moment` (aware), or let it run again (None)."""
        if moment is not None and moment.tzinfo is None:
            raise ValueError("the clock takes an aware datetime")
        self._fixed = moment

"""Tracks: the drawable geometry of a replay's track (the race viewer's background)."""
from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Body, HTTPException, status

from league.server.geometry import track_geometry

MAX_TRACK_BYTES = 32 * 1024  # a track dict is at most ~6 KB (64 control points, 20 obstacles)

router = APIRouter(prefix="/tracks", tags=["tracks"])


@router.post("/geometry")
def read_track_geometry(track: dict[str, Any] = Body(description="a track as in a replay (Track.to_dict)")) -> dict:
    """Drawable borders, obstacles and start of a replay's track (public; the race viewer's background)."""
    try:
        return track_geometry(track)
    except (KeyError, TypeError, ValueError) as error:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"not a track: {error}") from error

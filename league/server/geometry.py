"""Drawable geometry of a track for the web race viewer.

A replay stores its track compactly (control points and obstacle segments, `Track.to_dict`);
a browser needs polylines. `track_geometry` re-derives them with the simulator's own
`Track.from_dict`, so the page draws exactly the borders the cars raced on.
"""
from __future__ import annotations

import numpy as np

from league.track import CELLS_PER_UNIT, Track, obstacle_half_size

DECIMALS = 5  # 1e-5 world units = 1 cm, the replay's own precision


def track_geometry(track_dict: dict) -> dict:
    """Polylines of a track in world units (x right, y up), JSON-safe.

    Returns:
        {"inner": [[x, y], ...], "outer": [[x, y], ...]  (closed border polylines),
         "obstacles": [[[x0, y0], [x1, y1]], ...]          (segments),
         "width": float                                    (the road's width),
         "obstacle_half_width": float                      (half thickness of an obstacle),
         "start": {"x", "y", "heading"}                    (the start line and the race direction, rad)}

    Raises:
        ValueError, KeyError, TypeError: not a track dict of a known version.
    """
    track = Track.from_dict(track_dict)
    x, y = track.start_position
    return {
        "inner": _rounded(track.inner_border),
        "outer": _rounded(track.outer_border),
        "obstacles": _rounded(track.obstacles),
        "width": float(track.width),
        "obstacle_half_width": obstacle_half_size(track.width) / CELLS_PER_UNIT,
        "start": {"x": round(x, DECIMALS), "y": round(y, DECIMALS), "heading": round(track.start_heading, 4)},
    }


def _rounded(points: np.ndarray) -> list:
    return np.round(np.asarray(points, dtype=np.float64), DECIMALS).tolist()

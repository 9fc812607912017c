"""league.server.geometry: the track polylines the web race viewer draws."""
from __future__ import annotations

import json

import numpy as np
import pytest

from league.track import Track, generate_track
from league.server.geometry import track_geometry


@pytest.fixture(scope="module")
def track() -> Track:
    return generate_track(np.random.default_rng(5))


def test_geometry_is_the_tracks_own_borders_obstacles_and_start(track):
    geometry = json.loads(json.dumps(track_geometry(track.to_dict())))  # JSON-safe

    np.testing.assert_allclose(geometry["inner"], track.inner_border, atol=5e-6)
    np.testing.assert_allclose(geometry["outer"], track.outer_border, atol=5e-6)
    np.testing.assert_allclose(geometry["obstacles"], track.obstacles, atol=5e-6)
    assert geometry["width"] == track.width
    assert geometry["obstacle_half_width"] == pytest.approx(int(track.width * 500 / 4) / 500)
    start = geometry["start"]
    assert (start["x"], start["y"]) == pytest.approx(track.start_position, abs=5e-6)
    assert start["heading"] == pytest.approx(track.start_heading, abs=1e-4)


def test_a_replays_track_gives_the_same_geometry_as_the_track():
    from league.evaluation import race

    result = race(["heuristic"], seed=2)
    rebuilt = Track.from_dict(result.replay["track"])
    assert track_geometry(result.replay["track"])["outer"] == np.round(rebuilt.outer_border, 5).tolist()


@pytest.mark.parametrize("bad", [{}, {"version": 99}, {"version": 1, "width": 0.04}])
def test_not_a_track_raises(bad):
    with pytest.raises((KeyError, TypeError, ValueError)):
        track_geometry(bad)

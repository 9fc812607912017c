import math

import numpy as np
import pytest

import league
from league import lidar
from league.track import generate_track

from . import reference


@pytest.fixture(scope="module")
def track():
    return generate_track(np.random.default_rng(2024))


def random_poses(track, rng, n):
    """Random points inside random valid cells, with random headings."""
    cells = np.argwhere(track.valid)
    picks = cells[rng.integers(len(cells), size=n)]
    xy = (picks - 650 + rng.uniform(0.05, 0.95, size=(n, 2))) / 500
    # cell 650 spans (-1/500, 1/500) because int() truncates toward zero: keep the test points off it
    xy = np.where(np.abs(xy) < 1 / 500, 0.5 / 500 + 1 / 500, xy)
    return [(x, y, h) for (x, y), h in zip(xy, rng.uniform(-np.pi, np.pi, n)) if track.is_valid_position(x, y)]


def test_compiled_lidar_agrees_with_the_python_reference(track):
    poses = random_poses(track, np.random.default_rng(0), 300)
    assert len(poses) > 250
    for x, y, heading in poses:
        compiled = lidar.lidar(track.grid, x, y, heading)
        expected = reference.lidar(track.valid, x, y, heading)
        np.testing.assert_allclose(compiled, expected, atol=1e-12)


def test_readings_are_accurate_to_one_five_hundredth(track):
    """Against the ideal reading (a 1/5000-step march to the first blocked point).

    Cars at least two cells from the border. The 1/100 march can step over a one-cell tooth
    of the jagged (3x3-brush) border when a ray grazes it at a shallow angle; elsewhere the
    refinement makes the reading exact to 1/500.
    """
    errors = []
    for x, y, heading in random_poses(track, np.random.default_rng(1), 150):
        i, j = reference.cell(x), reference.cell(y)
        if not track.free[i - 2:i + 3, j - 2:j + 3].all():
            continue
        readings = lidar.lidar(track.grid, x, y, heading)
        for m, reading in enumerate(readings):
            angle = heading - math.pi / 6 + m * (math.pi / 3) / 18
            errors.append(reference.fine_ray(track.valid, x, y, angle) - reading)
    errors = np.array(errors)
    assert len(errors) > 1000
    within = np.abs(errors) <= 1 / 500 + 1e-9
    assert within.mean() > 0.95, within.mean()
    assert (errors[~within] < 0).all()  # the only misses are steps over a tooth, never short readings


def test_ray_angles_go_counter_clockwise_from_minus_30_degrees():
    # An open field of valid cells with a wall: a car at the origin facing +x, wall at x = 0.1.
    grid_valid = np.zeros((1300, 1300), dtype=bool)
    grid_valid[450:700, 400:900] = True  # x in [-0.4, 0.1), y in [-0.5, 0.5)
    grid = np.where(grid_valid, lidar.VALID_BIT, 0).astype(np.uint8)
    track_grid = _with_free_bits(grid)
    readings = lidar.lidar(track_grid, 0.0, 0.0, 0.0)
    assert readings[9] == pytest.approx(0.1, abs=0.005)  # straight ahead
    np.testing.assert_allclose(readings, readings[::-1], atol=0.004)  # symmetric wall
    assert readings[0] == pytest.approx(0.1 / math.cos(math.pi / 6), abs=0.005)
    # a wall only on the left (positive y) shortens the last rays, not the first ones
    grid_valid[:, 660:] = False  # y >= 0.02
    left = lidar.lidar(_with_free_bits(np.where(grid_valid, lidar.VALID_BIT, 0).astype(np.uint8)), 0.0, 0.0, 0.0)
    assert left[18] < 0.05 and left[0] > 0.1


def _with_free_bits(grid):
    valid = grid & lidar.VALID_BIT
    free = valid.copy()
    free[1:-1, 1:-1] = valid[1:-1, 1:-1] & valid[:-2, 1:-1] & valid[2:, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:]
    free[[0, -1], :] = 0
    free[:, [0, -1]] = 0
    return np.ascontiguousarray(grid | (free << 1))


def test_free_bits_match_the_definition(track):
    expected = _with_free_bits(np.ascontiguousarray(track.grid & lidar.VALID_BIT))
    np.testing.assert_array_equal(track.free, (expected & lidar.FREE_BIT).astype(bool))


@pytest.mark.parametrize("observation", ["compact", "lidar"])
def test_observation_is_built_from_the_lidar(observation):
    env = league.MicroRacerEnv(observation=observation)
    obs, _ = env.reset(seed=8)
    for _ in range(30):
        obs, _, terminated, _, info = env.step(reference.heuristic(_compact(env, obs)))
        assert not terminated
        cars = env.unwrapped.cars
        readings = reference.lidar(env.unwrapped.track.valid, cars.x[0], cars.y[0], cars.heading[0])
        expected = (reference.compact(readings, cars.speed[0]) if observation == "compact"
                    else readings + [cars.speed[0]])
        np.testing.assert_allclose(obs, np.float32(expected), atol=1 / 500)
        assert obs.dtype == np.float32 and env.observation_space.contains(obs)


def _compact(env, obs):
    if len(obs) == 5:
        return obs
    return reference.compact(list(obs[:19]), obs[19])

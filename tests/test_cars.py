"""Each rule of SPEC 'Car', checked on the Gymnasium env."""
import math

import numpy as np
import pytest

import league
from league.constants import CELLS_PER_UNIT, MAX_ACC, MAX_TURN, ORIGIN, TSTEP
from league.track import Track

from . import reference


def start(seed=0, speed=None, **options):
    env = league.MicroRacerEnv(**options)
    obs, info = env.reset(seed=seed, options=None if speed is None else {"initial_speed": speed})
    return env, obs, info


def state(env):
    c = env.unwrapped.cars
    return float(c.x[0]), float(c.y[0]), float(c.heading[0]), float(c.speed[0])


@pytest.mark.parametrize("speed", [0.1, 0.3, 0.45])
def test_turn_bound_with_the_limiter(speed):
    env, _, _ = start(speed=speed)
    heading0 = state(env)[2]
    env.step([0.0, 0.5])
    bound = min(MAX_TURN, 1.741 * TSTEP / speed)
    assert state(env)[2] == pytest.approx(heading0 - 0.5 * bound)


@pytest.mark.parametrize("speed", [0.1, 0.3])
def test_turn_bound_without_the_limiter(speed):
    env, _, _ = start(speed=speed, turn_limit=False)
    heading0 = state(env)[2]
    env.step([0.0, -0.5])  # negative turn = left = heading increases
    assert state(env)[2] == pytest.approx(heading0 + 0.5 * MAX_TURN)


def test_speed_and_position_update_and_reward_is_the_distance_covered():
    env, _, _ = start(seed=1, speed=0.3)
    x0, y0, h0, _ = state(env)
    _, reward, *_ = env.step([1.0, 0.2])
    x1, y1, h1, v1 = state(env)
    assert v1 == pytest.approx(0.3 + MAX_ACC * TSTEP)
    assert (x1, y1) == pytest.approx((x0 + v1 * math.cos(h1) * TSTEP, y0 + v1 * math.sin(h1) * TSTEP))
    assert reward == pytest.approx(math.hypot(x1 - x0, y1 - y0)) == pytest.approx(v1 * TSTEP)


def test_out_of_range_actions_are_clipped():
    a, _, _ = start(seed=2, speed=0.3)
    b, _, _ = start(seed=2, speed=0.3)
    ra = a.step([5.0, -7.0])
    rb = b.step([1.0, -1.0])
    np.testing.assert_array_equal(ra[0], rb[0])
    assert state(a) == state(b)


def test_off_road_crash_gives_minus_3_and_leaves_the_car_where_it_was():
    env, obs, _ = start(seed=3, speed=0.3)
    for _ in range(50):
        before = state(env)
        last_obs = obs
        obs, reward, terminated, truncated, info = env.step([0.0, 1.0])  # full right: into the outer border
        if terminated:
            break
    assert info["outcome"] == "off_road"
    assert reward == -3.0 and not truncated
    assert state(env)[:2] == before[:2]
    np.testing.assert_array_equal(obs, last_obs)  # the last valid observation


def test_obstacle_is_off_road():
    """A car driven straight at an obstacle ends off road; on the same track without obstacles the
    same step stays on the road (it may still be the wrong direction: off road is checked first)."""
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    track = env.unwrapped.track
    target = track.obstacles[0].mean(axis=0)
    cells = np.argwhere(track.valid)  # (x cell, y cell)
    xy = (cells - ORIGIN + 0.5) / CELLS_PER_UNIT
    near = xy[np.argmin(np.linalg.norm(xy - target, axis=1))]  # the valid cell nearest to the obstacle
    heading = math.atan2(target[1] - near[1], target[0] - near[0])

    def first_step(on: Track) -> str:
        env.reset(options={"track": on, "initial_speed": 0.25})
        env.unwrapped.cars.reset(float(near[0]), float(near[1]), heading, 0.25)
        return env.step([0.0, 0.0])[4]["outcome"]

    assert first_step(track) == "off_road"
    assert first_step(track.with_obstacles(np.empty((0, 2, 2)))) != "off_road"


def test_stopped_car_without_low_speed_termination_is_wrong_direction():
    # v' = 0: the polar angle does not strictly decrease
    env, _, _ = start(speed=0.0, low_speed_termination=False)
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert terminated and reward == -3.0 and info["outcome"] == "wrong_direction"


def test_turning_back_is_wrong_direction():
    env, _, _ = start(seed=0, speed=0.2, low_speed_termination=False, turn_limit=False)
    cars = env.unwrapped.cars
    x, y, heading, _ = state(env)
    cars.reset(x, y, heading + math.pi, 0.2)  # same spot, facing counter-clockwise
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert terminated and reward == -3.0 and info["outcome"] == "wrong_direction"


def test_too_slow_with_low_speed_termination():
    env, _, _ = start(speed=0.07)
    for _ in range(20):
        _, reward, terminated, _, info = env.step([-1.0, 0.0])
        if terminated:
            break
    assert info["outcome"] == "too_slow" and reward == -3.0
    assert state(env)[3] >= 0.05  # the failed move was not taken


def test_checks_run_in_order():
    """Off road before wrong direction, wrong direction before too slow."""
    env, _, _ = start(seed=0)
    x, y, _, _ = state(env)  # on the positive x axis: outward is +x, counter-clockwise is +y
    cars = env.unwrapped.cars
    cars.reset(x, y, math.pi / 4, 1.0)  # outward and backward, fast enough to leave the road
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert (info["outcome"], reward, terminated) == ("off_road", -3.0, True)
    cars.reset(x, y, math.pi / 2, 0.04)  # backward and too slow, still on the road
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert (info["outcome"], reward, terminated) == ("wrong_direction", -3.0, True)


def test_lap_is_completed_clockwise():
    env, obs, info = start(seed=5,
                           **{k: False for k in ("obstacles", "chicanes", "turn_limit", "low_speed_termination")})
    progress = [info["progress"]]
    while True:
        obs, reward, terminated, truncated, info = env.step(reference.heuristic(obs))
        progress.append(info["progress"])
        if terminated or truncated:
            break
    assert info["outcome"] == "finished" and reward > 0
    assert progress[0] == 0.0 and progress[-1] == 1.0
    assert all(b >= a for a, b in zip(progress, progress[1:]))  # always moving clockwise
    assert info["distance"] == pytest.approx(env.unwrapped.track.length, rel=0.05)
    assert info["time"] == pytest.approx((len(progress) - 1) * TSTEP)


def test_start_speed_floor():
    speeds_on = [league.MicroRacerEnv().reset(seed=s)[1]["speed"] for s in range(200)]
    speeds_off = [league.MicroRacerEnv(low_speed_termination=False).reset(seed=s)[1]["speed"] for s in range(200)]
    assert min(speeds_on) >= 0.07 and max(speeds_on) <= 0.5
    assert min(speeds_off) < 0.07 and max(speeds_off) <= 0.5


def test_time_limit_truncates():
    env, obs, _ = start(seed=5, max_episode_steps=20)
    for _step in range(20):
        obs, _, terminated, truncated, info = env.step(reference.heuristic(obs))
    assert truncated and not terminated and info["outcome"] == "running"


def test_the_compiled_core_uses_the_numbers_of_league_constants():
    """setup.py compiles league/constants.py into the core: one home for every number."""
    from league import constants, lidar

    env = league.MicroRacerEnv(observation="lidar")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (constants.LIDAR_DIM,) and len(lidar.lidar(env.track.grid, 0.9, 0.0, 0.0)) == constants.N_RAYS
    assert env.track.grid.shape == (constants.GRID, constants.GRID)
    env.unwrapped.cars.reset(*env.track.start_position, math.pi / 2, 0.3)  # backward: wrong direction
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert terminated and reward == constants.CRASH_REWARD
    assert constants.OUTCOMES[constants.WRONG_DIRECTION] == info["outcome"]
    speed = env.reset(seed=1, options={"initial_speed": 0.2})[0][-1]
    env.step([1.0, 0.0])
    assert env.unwrapped.cars.speed[0] == pytest.approx(speed + constants.MAX_ACC * constants.TSTEP)

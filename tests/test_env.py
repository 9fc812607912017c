import json
import pickle
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import league

from . import reference

ALL_OFF = dict(obstacles=False, chicanes=False, turn_limit=False, low_speed_termination=False)


@pytest.mark.parametrize("options", [{}, ALL_OFF, {"observation": "lidar"}, {"curves": 12, "n_obstacles": 3, "track_width": 0.05}])
def test_gymnasium_env_checker(options):
    env = gym.make("league/MicroRacer-v0", **options)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.shape == (5 if options.get("observation") != "lidar" else 20,)
    assert env.observation_space.contains(obs)


def rollout(seed, steps=300, **options):
    env = league.MicroRacerEnv(**options)
    obs, info = env.reset(seed=seed)
    trace = [obs.tolist(), info]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(reference.heuristic(obs))
        trace.append([obs.tolist(), reward, terminated, truncated, info])
        if terminated or truncated:
            obs, info = env.reset()
            trace.append([obs.tolist(), info])
    return trace


def test_same_seed_same_rollout_in_two_processes():
    code = "import json, tests.test_env as t; print(json.dumps(t.rollout(42, 1500)))"
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert json.loads(other) == json.loads(json.dumps(rollout(42, 1500)))


def test_different_seeds_differ():
    assert rollout(1, 50) != rollout(2, 50)


def test_reset_without_seed_continues_the_stream_and_options_reuse_a_track():
    env = league.MicroRacerEnv()
    env.reset(seed=3)
    first = env.unwrapped.track
    env.reset()
    assert env.unwrapped.track != first
    obs, info = env.reset(options={"track": first, "initial_speed": 0.2})
    assert env.unwrapped.track is first and info["speed"] == pytest.approx(0.2)


def test_done_step_returns_a_full_valid_observation():
    env = league.MicroRacerEnv()
    obs, _ = env.reset(seed=0)
    while True:
        obs, _, terminated, truncated, info = env.step([0.0, 1.0])
        if terminated or truncated:
            break
    assert obs.shape == (5,) and env.observation_space.contains(obs)


@pytest.mark.parametrize(
    "action, message",
    [
        ([0.1, 0.2, 0.3], r"shape \(2,\)"),
        ([[0.1], [0.2]], r"shape \(2,\)"),
        ([np.nan, 0.0], "NaN"),
        ([0.0, float("nan")], "NaN"),
        ("ab", "numbers"),
        (None, "numbers|shape"),
    ],
)
def test_bad_actions_are_clear_errors_and_the_env_keeps_working(action, message):
    env = league.MicroRacerEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)
    obs, reward, terminated, *_ = env.step([0.1, 0.0])  # nothing moved on the bad call
    assert reward > 0 and not terminated and env.unwrapped.cars.steps_taken[0] == 1


@pytest.mark.parametrize(
    "options, message",
    [
        ({"observation": "pixels"}, "observation must be one of"),
        ({"curves": 2}, "curves must be an integer >= 5"),
        ({"track_width": 0}, "track_width"),
        ({"track_width": 1.0}, "track_width"),
        ({"obstacles": "yes"}, "obstacles must be True or False"),
        ({"n_obstacles": -2}, "n_obstacles"),
        ({"tstep": 0}, "tstep"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
    ],
)
def test_bad_options_are_clear_errors(options, message):
    with pytest.raises(ValueError, match=message):
        league.MicroRacerEnv(**options)


def test_unknown_option_names_the_valid_ones():
    with pytest.raises(TypeError, match="unknown MicroRacer option.*obstacle.*valid options"):
        league.MicroRacerEnv(obstacle=False)


def test_step_before_reset_and_after_the_end_are_clear_errors():
    env = league.MicroRacerEnv()
    with pytest.raises(RuntimeError, match="reset"):
        env.step([0, 0])
    env2 = league.MicroRacerEnv(low_speed_termination=False)
    env2.reset(seed=0, options={"initial_speed": 0.0})
    env2.step([0, 0])  # stopped: wrong direction
    with pytest.raises(RuntimeError, match="episode is over"):
        env2.step([0, 0])


def test_pickled_env_continues_identically():
    env = league.MicroRacerEnv()
    obs, _ = env.reset(seed=9)
    for _ in range(20):
        obs, *_ = env.step(reference.heuristic(obs))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(50):
        action = reference.heuristic(obs)
        a, b = env.step(action), clone.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]
        obs = a[0]
        if a[2] or a[3]:
            break


def test_info_fields():
    env = league.MicroRacerEnv()
    obs, info = env.reset(seed=0)
    assert set(info) >= {"outcome", "progress", "time", "distance", "speed"}
    assert info["outcome"] == "running" and info["progress"] == 0.0 and info["time"] == 0.0
    obs, reward, *_, info = env.step(reference.heuristic(obs))
    assert info["time"] == pytest.approx(0.04) and info["distance"] == pytest.approx(reward)
    assert 0 < info["progress"] < 0.01
    json.dumps(info)  # plain Python types


def test_rgb_array_render_draws_track_obstacles_car_and_trail_without_a_display():
    env = gym.make("league/MicroRacer-v0", render_mode="rgb_array")
    obs, _ = env.reset(seed=5)
    first = env.render()
    for _ in range(100):
        obs, *_ = env.step(reference.heuristic(obs))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3 and min(frame.shape[:2]) > 300
    colours = {tuple(c) for c in frame.reshape(-1, 3)[:: 7]}
    assert len(colours) >= 4  # background, road, obstacles, car/trail
    assert (frame != first).any(axis=2).sum() > 50  # the trail grew


def test_parallel_render_draws_every_car():
    penv = league.parallel_env(n_cars=3, render_mode="rgb_array")
    observations, _ = penv.reset(seed=2)
    for step in range(60):
        actions = {a: np.array(reference.heuristic(observations[a])) * (1 + 0.3 * int(a[4:])) for a in penv.agents}
        observations, *_ = penv.step(actions)
    frame = penv.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8

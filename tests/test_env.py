import json
import pickle
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import league
from league.constants import OBSERVATION_DIMS, observation_name

from . import reference

ALL_OFF = dict(obstacles=False, chicanes=False, turn_limit=False, low_speed_termination=False)


@pytest.mark.parametrize("options", [{}, ALL_OFF, {"observation": "lidar"},
                                     {"curves": 12, "n_obstacles": 3, "track_width": 0.05}])
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



def test_one_table_names_the_observations_and_their_sizes():
    assert OBSERVATION_DIMS == {"compact": 5, "lidar": 20}
    for name, dim in OBSERVATION_DIMS.items():
        assert observation_name(dim) == name and league.RaceOptions(observation=name).obs_dim == dim
        assert league.MicroRacerEnv(observation=name).observation_space.shape == (dim,)
    with pytest.raises(ValueError, match=r"an observation has 5 numbers \(compact\) or 20 \(lidar\), not 6"):
        observation_name(6)

def test_same_seed_same_rollout_in_two_processes():
    code = "import json, tests.test_env as t; print(json.dumps(t.rollout(42, 1500), default=t.number))"
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert json.loads(other) == json.loads(json.dumps(rollout(42, 1500), default=number))


def number(value: np.generic):
    """A numpy scalar of an info as JSON sees it."""
    return value.item()


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
        ({"curves": 2}, r"curves must be an integer in \[5, 60\]"),
        ({"track_width": 0}, "track_width"),
        ({"track_width": 1.0}, "track_width"),
        ({"obstacles": "yes"}, "obstacles must be True or False"),
        ({"n_obstacles": -2}, "n_obstacles"),
        ({"tstep": 0}, "tstep"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
        # what a course can use: a huge track takes minutes to draw, a tiny step a huge replay
        ({"curves": 1_000_000}, "curves must be an integer in \\[5, 60\\], got 1000000"),
        ({"n_obstacles": 21}, "n_obstacles must be an integer in \\[0, 20\\]"),
        ({"tstep": 1e-9}, "tstep must be in \\[0.01, 0.2\\] seconds"),
        ({"max_episode_steps": 10**9}, "max_episode_steps must be an integer in \\[1, 20000\\]"),
    ],
)
def test_bad_options_are_clear_errors(options, message):
    with pytest.raises(ValueError, match=message):
        league.MicroRacerEnv(**options)


def test_unknown_option_is_pythons_own_error_and_names_the_valid_ones():
    with pytest.raises(TypeError, match=r"^MicroRacerEnv.__init__\(\) got an unexpected keyword argument 'obstacle'; "
                                        r"valid options: .*'obstacles'"):
        league.MicroRacerEnv(obstacle=False)
    with pytest.raises(TypeError, match="unexpected keyword argument 'frameskip'"):  # what torchrl probes for
        gym.make("league/MicroRacer-v0", frameskip=1)


def test_time_limit_belongs_to_gymnasiums_registry():
    env = gym.make("league/MicroRacer-v0", low_speed_termination=False)
    assert env.spec.max_episode_steps == league.constants.MAX_EPISODE_STEPS
    assert env.unwrapped.options.max_episode_steps is None  # the TimeLimit wrapper keeps time
    short = gym.make("league/MicroRacer-v0", max_episode_steps=30, low_speed_termination=False)
    assert short.spec.max_episode_steps == 30
    obs, _ = short.reset(seed=0)
    for step in range(1, 31):
        obs, _, terminated, truncated, info = short.step(reference.heuristic(obs))
        assert not terminated and truncated == (step == 30)
    assert info["outcome"] == "running"
    direct = league.MicroRacerEnv(max_episode_steps=5)  # built directly, the env keeps time itself
    obs, _ = direct.reset(seed=0)
    truncations = []
    for _ in range(5):
        obs, _, _, truncated, _ = direct.step(reference.heuristic(obs))
        truncations.append(truncated)
    assert truncations == [False] * 4 + [True]


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
    assert set(info) == {"outcome", "outcome_code", "progress", "time", "distance", "speed"}
    assert info["outcome"] == "running" and info["outcome_code"] == 0
    assert info["progress"] == 0.0 and info["time"] == 0.0
    obs, reward, *_, info = env.step(reference.heuristic(obs))
    assert info["time"] == pytest.approx(0.04) and info["distance"] == pytest.approx(reward)
    assert 0 < info["progress"] < 0.01
    # numpy scalars, as torchrl's info reader needs (it reads their dtype)
    assert type(info["outcome_code"]) is np.int64 and type(info["outcome"]) is str
    assert all(type(info[key]) is np.float64 for key in ("progress", "time", "distance", "speed"))


def test_numeric_infos_leave_the_outcome_name_out():
    env = gym.make("league/MicroRacer-v0", numeric_infos=True)
    obs, info = env.reset(seed=0)
    assert set(info) == {"outcome_code", "progress", "time", "distance", "speed"}
    obs, *_, info = env.step(reference.heuristic(obs))
    assert set(info) == {"outcome_code", "progress", "time", "distance", "speed"}
    assert all(value.dtype.kind in "if" for value in info.values())


def test_info_has_the_same_keys_and_types_at_every_step_and_the_code_names_the_outcome():
    env = league.MicroRacerEnv()
    obs, first = env.reset(seed=1)
    types = {key: type(value) for key, value in first.items()}
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(np.array(reference.heuristic(obs)) * [1.6, 1])
        assert {key: type(value) for key, value in info.items()} == types
    assert info["outcome"] != "running" and league.constants.OUTCOMES[info["outcome_code"]] == info["outcome"]


def test_rgb_array_frames_have_the_declared_shape_on_every_track_and_before_reset():
    env = gym.make("league/MicroRacer-v0", render_mode="rgb_array")
    shape = env.metadata["render_frame_shape"]
    assert env.unwrapped.render().shape == shape  # Gymnasium's pixel wrappers render before the first reset
    for seed in range(3):
        env.reset(seed=seed)
        frame = env.render()
        assert frame.shape == shape and frame.dtype == np.uint8


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
    penv = league.make_parallel_env(n_cars=3, render_mode="rgb_array")
    observations, _ = penv.reset(seed=2)
    for _step in range(60):
        actions = {a: np.array(reference.heuristic(observations[a])) * (1 + 0.3 * int(a[4:])) for a in penv.agents}
        observations, *_ = penv.step(actions)
    frame = penv.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8

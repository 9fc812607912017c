import pickle
from types import SimpleNamespace

import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test, state_test

import league

from . import reference

ALL_OFF = dict(obstacles=False, chicanes=False, turn_limit=False, low_speed_termination=False)


@pytest.mark.parametrize("options", [{}, ALL_OFF, {"observation": "lidar"}])
def test_pettingzoo_parallel_api(options):
    parallel_api_test(league.make_parallel_env(n_cars=3, **options), num_cycles=300)


@pytest.mark.parametrize("options", [{}, ALL_OFF])
def test_pettingzoo_parallel_seed(options):
    parallel_seed_test(lambda: league.make_parallel_env(n_cars=3, **options), num_cycles=100)


def test_aec_form():
    api_test(league.make_aec_env(n_cars=2), num_cycles=100)


def seeded(make, seed: int):
    """`make(**kwargs)` with its env's tracks and its action spaces' samples drawn from `seed`."""
    def seeded_make(**kwargs):
        env = make(**kwargs)
        env.reset(seed=seed)  # the test's own reset() draws the next track from this stream
        for i, agent in enumerate(env.possible_agents):
            env.action_space(agent).seed(seed + i)
        return env
    return seeded_make


def test_pettingzoo_max_cycles_is_the_episode_limit():
    # PettingZoo's test drives random actions and wants most cars alive after max_cycles=4
    # steps; a random car can leave the road that soon, so its envs are seeded.
    module = SimpleNamespace(parallel_env=seeded(league.make_parallel_env, 3), env=seeded(league.make_aec_env, 3))
    max_cycles_test(module)
    assert league.make_parallel_env(max_cycles=7).options.max_episode_steps == 7
    with pytest.raises(TypeError, match="max_cycles .* or max_episode_steps, not both"):
        league.make_parallel_env(max_cycles=7, max_episode_steps=7)


def test_pettingzoo_state():
    state_test(league.make_aec_env(n_cars=3), league.make_parallel_env(n_cars=3), num_cycles=100)


def test_pettingzoo_render():
    render_test(lambda render_mode=None: league.make_aec_env(n_cars=2, render_mode=render_mode))
    penv = league.make_parallel_env(n_cars=2, render_mode="rgb_array")
    assert penv.render().shape == penv.metadata["render_frame_shape"]  # before reset too


def test_spaces_are_dict_attributes_too():
    penv = league.make_parallel_env(n_cars=3)
    for agent in penv.possible_agents:
        assert penv.observation_spaces[agent] is penv.observation_space(agent)
        assert penv.action_spaces[agent] is penv.action_space(agent)


def test_state_is_every_cars_position_heading_and_speed():
    penv = league.make_parallel_env(n_cars=3)
    with pytest.raises(RuntimeError, match="reset"):
        penv.state()
    observations, _ = penv.reset(seed=4)
    for _ in range(40):
        actions = {a: np.array(reference.heuristic(observations[a])) * [1, 1 + int(a[4:])] for a in penv.agents}
        observations, *_ = penv.step(actions)
    state = penv.state()
    assert state.shape == penv.state_space.shape == (12,) and penv.state_space.contains(state)
    cars = penv.car_states()
    per_car = state.reshape(3, 4)
    np.testing.assert_allclose(per_car[:, [0, 1, 3]], np.column_stack([cars["x"], cars["y"], cars["speed"]]), rtol=1e-6)
    np.testing.assert_allclose(np.cos(per_car[:, 2]), np.cos(cars["heading"]), atol=1e-6)
    np.testing.assert_allclose(np.sin(per_car[:, 2]), np.sin(cars["heading"]), atol=1e-6)


def test_infos_have_the_same_keys_and_types_from_reset_to_the_end():
    penv = league.make_parallel_env(n_cars=4, **ALL_OFF)
    observations, infos = penv.reset(seed=4)
    types = {key: type(value) for key, value in infos["car_0"].items()}
    assert set(types) == {"outcome", "outcome_code", "progress", "time", "distance", "speed", "position", "finish_time"}
    assert infos["car_0"]["position"] == 0 and infos["car_0"]["finish_time"] == 0.0
    last = {}
    while penv.agents:
        actions = {a: np.array(reference.heuristic(observations[a])) * [1 + 0.3 * int(a[4:]), 1] for a in penv.agents}
        observations, _, _, _, infos = penv.step(actions)
        for info in infos.values():
            assert {key: type(value) for key, value in info.items()} == types
        last.update(infos)
    finishers = [i for i in last.values() if i["outcome"] == "finished"]
    assert finishers and all(i["position"] >= 1 and i["finish_time"] > 0 for i in finishers)
    assert all(league.constants.OUTCOMES[i["outcome_code"]] == i["outcome"] for i in last.values())


def test_numeric_infos_leave_the_outcome_name_out():
    penv = league.make_parallel_env(n_cars=2, numeric_infos=True)
    _, infos = penv.reset(seed=0)
    assert "outcome" not in infos["car_0"] and all(isinstance(v, np.number) for v in infos["car_0"].values())


def drive(penv, seed, perturb=0.0):
    """Heuristic driver for every car, car i's acceleration shifted by i * perturb."""
    observations, infos = penv.reset(seed=seed)
    last = dict(infos)
    while penv.agents:
        actions = {}
        for agent in penv.agents:
            acc, turn = reference.heuristic(observations[agent])
            actions[agent] = np.array([acc + int(agent[4:]) * perturb, turn], dtype=np.float32)
        observations, _, _, _, infos = penv.step(actions)
        last.update(infos)
    return last


def test_cars_share_track_start_and_speed_and_identical_actions_give_identical_races():
    penv = league.make_parallel_env(n_cars=4)
    observations, infos = penv.reset(seed=3)
    assert len({tuple(o) for o in observations.values()}) == 1
    assert len({i["speed"] for i in infos.values()}) == 1
    final = drive(penv, 3)
    assert len({(i["outcome"], i["distance"], i["time"]) for i in final.values()}) == 1


def test_finishing_positions_follow_interpolated_finish_times():
    penv = league.make_parallel_env(n_cars=8, **ALL_OFF)
    final = drive(penv, 4, perturb=0.004)
    finishers = [i for i in final.values() if i["outcome"] == "finished"]
    assert len(finishers) >= 4
    by_time = sorted(finishers, key=lambda i: i["finish_time"])
    assert [i["position"] for i in by_time] == list(range(1, len(finishers) + 1))
    times = [i["finish_time"] for i in by_time]
    assert len(set(times)) == len(times)
    # interpolated inside the crossing step: not a whole number of steps, within that step
    for info in finishers:
        assert info["time"] - 0.04 < info["finish_time"] <= info["time"]
    # some cars crossed in the same step and are still ordered
    assert len({round(i["time"], 6) for i in finishers}) < len(finishers)


def test_done_cars_leave_the_agents_and_their_actions_are_ignored():
    penv = league.make_parallel_env(n_cars=2)
    observations, _ = penv.reset(seed=0)
    for _ in range(30):  # car_0 steers full right into the border, car_1 drives well
        actions = {"car_0": [0.0, 1.0], "car_1": reference.heuristic(observations["car_1"])}
        observations, _, terminations, _, _ = penv.step({a: actions[a] for a in penv.agents})
        if "car_0" not in penv.agents:
            break
    assert terminations["car_0"] and penv.agents == ["car_1"]
    x, y = penv.cars.x[0], penv.cars.y[0]
    observations, *_ = penv.step({"car_0": [1.0, 1.0], "car_1": reference.heuristic(observations["car_1"])})
    assert set(observations) == {"car_1"} and (penv.cars.x[0], penv.cars.y[0]) == (x, y)  # ignored, as PettingZoo does
    with pytest.raises(ValueError, match=r"unknown agents \['car_7'\]"):
        penv.step({"car_7": [0, 0], "car_1": [0, 0]})
    with pytest.raises(ValueError, match="missing actions"):
        penv.step({})
    with pytest.raises(ValueError, match="NaN"):
        penv.step({"car_1": [np.nan, 0]})
    with pytest.raises(ValueError, match="unknown agent"):
        penv.info("car_99")


def test_batched_interface_matches_the_dict_interface():
    a, b = league.make_parallel_env(n_cars=5), league.make_parallel_env(n_cars=5)
    obs_a, _ = a.reset(seed=12)
    b.reset(seed=12)
    obs = np.stack([obs_a[x] for x in a.possible_agents])
    rng = np.random.default_rng(0)
    while a.agents:
        actions = np.array([reference.heuristic(o) for o in obs], dtype=np.float32)
        actions[:, 0] += rng.normal(0, 0.05, len(actions)).astype(np.float32)
        live = list(a.agents)
        obs_d, rew_d, term_d, trunc_d, info_d = a.step({x: actions[int(x[4:])] for x in live})
        obs_b, rew_b, term_b, trunc_b = b.step_arrays(actions)
        assert b.agents == a.agents  # step_arrays, too, takes the cars done out of `agents`
        for x in live:
            i = int(x[4:])
            np.testing.assert_array_equal(obs_d[x], obs_b[i])
            assert (rew_d[x], term_d[x], trunc_d[x]) == (rew_b[i], term_b[i], trunc_b[i])
            assert b.info(x) == info_d[x]
        obs = obs_b.copy()
    assert not (b.cars.outcome == 0).any()


def test_car_states_and_pickling():
    penv = league.make_parallel_env(n_cars=3)
    observations, _ = penv.reset(seed=1)
    states = penv.car_states()
    assert set(states) == {"x", "y", "heading", "speed"} and states["x"].shape == (3,)
    clone = pickle.loads(pickle.dumps(penv))
    actions = {a: reference.heuristic(observations[a]) for a in penv.agents}
    ra, rb = penv.step(actions), clone.step(actions)
    assert ra[1:] == rb[1:]


def test_bad_n_cars():
    with pytest.raises(ValueError, match="n_cars"):
        league.make_parallel_env(n_cars=0)


def test_retire_takes_a_car_out_of_the_race():
    penv = league.make_parallel_env(n_cars=2)
    observations, _ = penv.reset(seed=0)
    penv.retire("car_0")
    assert penv.agents == ["car_1"]
    _, _, _, _, infos = penv.step({"car_1": reference.heuristic(observations["car_1"])})
    assert penv.cars.info(0)["outcome"] == "retired" and infos["car_1"]["outcome"] == "running"
    with pytest.raises(ValueError, match="not racing"):
        penv.retire("car_0")

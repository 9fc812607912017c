"""league.vector_env: the native Gymnasium vector env, against N single envs and Gymnasium's own."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import league
from league.agents import compact_from_lidar, heuristic_actions

INFO_KEYS = ("outcome", "progress", "time", "distance", "speed")


def drive(obs):
    """SPEC's heuristic driver on a batch of compact or lidar observations."""
    return heuristic_actions(obs if obs.shape[1] == 5 else compact_from_lidar(obs))


def assert_same_step(vector, singles, i):
    obs, reward, terminated, truncated, infos = vector
    single_obs, single_reward, single_terminated, single_truncated, info = singles
    np.testing.assert_array_equal(obs[i], single_obs)
    assert (reward[i], terminated[i], truncated[i]) == (single_reward, single_terminated, single_truncated)
    assert {key: infos[key][i] for key in INFO_KEYS} == {key: info[key] for key in INFO_KEYS}


def run_against_single_envs(steps, num_envs=4, seed=11, **options):
    """Step the vector env and N MicroRacerEnv (seeds seed + i, autoreset at the next step by hand)
    with the same actions; every observation, reward, flag and info must be identical."""
    venv = league.make_vector_env(num_envs=num_envs, **options)
    singles = [league.MicroRacerEnv(**options) for _ in range(num_envs)]
    obs, infos = venv.reset(seed=seed)
    for i, env in enumerate(singles):
        single_obs, info = env.reset(seed=seed + i)
        assert_same_step((obs, np.zeros(num_envs), np.zeros(num_envs, bool), np.zeros(num_envs, bool), infos),
                         (single_obs, 0.0, False, False, info), i)
    done, episodes = [False] * num_envs, 0
    for _ in range(steps):
        actions = drive(obs)
        step = venv.step(actions)
        for i, env in enumerate(singles):
            if done[i]:
                single = (*env.reset(), )
                single = (single[0], 0.0, False, False, single[1])
            else:
                single = env.step(actions[i])
            assert_same_step(step, single, i)
            done[i] = single[2] or single[3]
            episodes += done[i]
        obs = step[0]
    return episodes


def test_trajectories_equal_n_single_envs_through_autoresets():
    # 900 steps: every sub-env finishes or crashes at least once and starts again on a new track
    assert run_against_single_envs(900) >= 4


@pytest.mark.parametrize("options", [
    {"obstacles": False}, {"chicanes": False}, {"turn_limit": False}, {"low_speed_termination": False},
    {"observation": "lidar"}, {"curves": 12}, {"track_width": 0.06}, {"n_obstacles": 2}, {"tstep": 0.05},
    {"max_episode_steps": 60},
])
def test_every_option_as_the_single_env(options):
    run_against_single_envs(150, num_envs=3, **options)


def test_stepping_some_sub_envs_leaves_the_others_exactly_as_they_were():
    venv = league.make_vector_env(num_envs=4, max_episode_steps=30)
    singles = {0: league.MicroRacerEnv(max_episode_steps=30), 2: league.MicroRacerEnv(max_episode_steps=30)}
    obs, _ = venv.reset(seed=5)
    for i, env in singles.items():
        env.reset(seed=5 + i)
    moving, still, done = np.array([True, False, True, False]), obs[[1, 3]].copy(), {0: False, 2: False}
    for _ in range(80):  # through the time limit and the next-step autoreset of the moving ones
        actions = drive(obs)
        step = venv.step(actions, moving=moving)
        obs, reward, terminated, truncated, _ = step
        np.testing.assert_array_equal(obs[[1, 3]], still)
        assert not (reward[[1, 3]].any() or terminated[[1, 3]].any() or truncated[[1, 3]].any())
        for i, env in singles.items():
            if done[i]:
                reset_obs, info = env.reset()
                single = (reset_obs, 0.0, False, False, info)
            else:
                single = env.step(actions[i])
            assert_same_step(step, single, i)
            done[i] = single[2] or single[3]


def test_truncation_counts_each_cars_own_steps():
    venv = league.make_vector_env(num_envs=2, max_episode_steps=40, obstacles=False, chicanes=False)
    obs, _ = venv.reset(seed=2)
    venv.cars.retire(1)  # car 1 ends now (as a crash would), and starts again at the next step
    venv._needs_reset[1] = True
    for step in range(1, 43):
        obs, _, terminated, truncated, infos = venv.step(drive(obs))
        assert not terminated.any()
        assert truncated.tolist() == [step == 40, step == 41]  # car 1's episode began one step later
        assert infos["outcome"].tolist() == ["running", "running"]
    assert infos["time"].tolist() == [pytest.approx(0.04), 0.0]  # both started again


def test_same_step_autoreset_gives_final_observations_and_infos():
    venv = league.make_vector_env(num_envs=3, autoreset_mode=AutoresetMode.SAME_STEP, max_episode_steps=50)
    single = league.MicroRacerEnv(max_episode_steps=50)
    obs, _ = venv.reset(seed=4)
    single_obs, _ = single.reset(seed=4)
    for _ in range(50):
        actions = drive(obs)
        obs, rewards, terminated, truncated, infos = venv.step(actions)
        single_obs, *_, info = single.step(actions[0])
    assert truncated.all() and infos["_final_obs"].all() and infos["_final_info"].all()
    np.testing.assert_array_equal(infos["final_obs"][0], single_obs)
    assert infos["final_info"]["outcome"][0] == "running" and infos["final_info"]["time"][0] == info["time"]
    np.testing.assert_array_equal(obs[0], single.reset()[0])  # already the next episode's start
    assert (infos["time"] == 0).all() and (infos["outcome"] == "running").all()


def test_same_step_autoreset_matches_gymnasiums_sync_vector_env():
    kwargs = {"num_envs": 3, "vector_kwargs": {"autoreset_mode": AutoresetMode.SAME_STEP}}
    sync = gym.make_vec("league/MicroRacer-v0", vectorization_mode="sync", max_episode_steps=120, **kwargs)
    native = league.make_vector_env(num_envs=3, autoreset_mode=AutoresetMode.SAME_STEP, max_episode_steps=120)
    sync_obs, _ = sync.reset(seed=8)
    obs, _ = native.reset(seed=8)
    for _ in range(300):
        actions = drive(obs)
        step, sync_step = native.step(actions), sync.step(actions)
        for mine, theirs in zip(step[:4], sync_step[:4]):
            np.testing.assert_array_equal(mine, theirs)
        assert set(step[4].get("_final_obs", np.zeros(3)).nonzero()[0]) == set(
            sync_step[4].get("_final_obs", np.zeros(3)).nonzero()[0])
        obs = step[0]


def test_next_step_autoreset_matches_make_vec_sync_and_infos_are_arrays():
    sync = gym.make_vec("league/MicroRacer-v0", num_envs=4, vectorization_mode="sync")
    native = gym.make_vec("league/MicroRacer-v0", num_envs=4, vectorization_mode="vector_entry_point")
    assert isinstance(native.unwrapped, league.MicroRacerVectorEnv)
    assert native.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, infos = native.reset(seed=5)
    np.testing.assert_array_equal(obs, sync.reset(seed=5)[0])
    for _ in range(700):
        actions = drive(obs)
        step, sync_step = native.step(actions), sync.step(actions)
        for mine, theirs in zip(step[:4], sync_step[:4]):
            np.testing.assert_array_equal(mine, theirs)
        for key in INFO_KEYS:
            np.testing.assert_array_equal(step[4][key], sync_step[4][key])
        obs, infos = step[0], step[4]
    assert infos["outcome_code"].dtype == np.int64 and infos["_outcome"].all()
    assert set(infos["outcome"]) <= set(league.constants.OUTCOMES)


def test_numeric_infos_leave_the_outcome_name_out_as_sync_vector_env_does():
    kwargs = {"num_envs": 3, "max_episode_steps": 40, "numeric_infos": True}
    sync = gym.make_vec("league/MicroRacer-v0", vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}, **kwargs)
    native = league.make_vector_env(autoreset_mode=AutoresetMode.SAME_STEP, **kwargs)
    obs, infos = native.reset(seed=2)
    assert set(infos) == set(sync.reset(seed=2)[1]) and "outcome" not in infos and "_outcome" not in infos
    finals = 0
    for _ in range(90):  # two truncations at least: final infos
        step, sync_step = native.step(drive(obs)), sync.step(drive(obs))
        infos, sync_infos = step[4], sync_step[4]
        assert set(infos) == set(sync_infos)
        assert set(infos.get("final_info", {})) == set(sync_infos.get("final_info", {}))
        for key in INFO_KEYS[1:]:
            np.testing.assert_array_equal(infos[key], sync_infos[key])
        finals += "final_info" in infos
        obs = step[0]
    assert finals >= 2


def test_spaces_and_batches_follow_gymnasium():
    venv = league.make_vector_env(num_envs=5, observation="lidar")
    assert venv.single_observation_space == league.MicroRacerEnv(observation="lidar").observation_space
    assert venv.observation_space.shape == (5, 20) and venv.action_space.shape == (5, 2)
    obs, _ = venv.reset(seed=0)
    assert obs.dtype == np.float32 and venv.observation_space.contains(obs)
    venv.action_space.seed(0)
    obs, rewards, terminated, truncated, _ = venv.step(venv.action_space.sample())
    assert venv.observation_space.contains(obs)
    assert rewards.shape == terminated.shape == truncated.shape == (5,) and terminated.dtype == np.bool_


def test_works_under_gymnasiums_vector_wrappers():
    venv = gym.wrappers.vector.RecordEpisodeStatistics(league.make_vector_env(num_envs=4))
    obs, _ = venv.reset(seed=1)
    lengths = []
    for _ in range(800):
        obs, _, _, _, infos = venv.step(drive(obs))
        if "episode" in infos:
            lengths += infos["episode"]["l"][infos["_episode"]].tolist()
    assert len(lengths) >= 4 and all(length > 10 for length in lengths)


def test_seeding_reproduces_every_sub_env_and_seed_lists_work():
    venv = league.make_vector_env(num_envs=3)
    first, _ = venv.reset(seed=21)
    tracks = list(venv.tracks)
    again, _ = venv.reset(seed=21)
    np.testing.assert_array_equal(first, again)
    assert venv.tracks == tracks and len(set(map(hash, tracks))) == 3
    other, _ = venv.reset(seed=[22, 23, 24])
    assert venv.tracks[:2] == tracks[1:] and venv.tracks[2] != tracks[2]
    unseeded, _ = venv.reset()
    assert venv.tracks != tracks  # the sub-envs' generators carry on


def test_disabled_autoreset_needs_an_explicit_reset_of_done_sub_envs():
    venv = league.make_vector_env(num_envs=2, autoreset_mode="Disabled", max_episode_steps=10)
    obs, _ = venv.reset(seed=3)
    for _ in range(10):
        obs, _, _, truncated, _ = venv.step(drive(obs))
    assert truncated.all()
    with pytest.raises(RuntimeError, match="reset_mask"):
        venv.step(drive(obs))
    obs, infos = venv.reset(options={"reset_mask": np.array([True, False])})
    assert infos["time"][0] == 0 and infos["time"][1] == pytest.approx(0.4)
    with pytest.raises(RuntimeError, match=r"sub-envs \[1\] are done"):
        venv.step(drive(obs))


def test_a_track_pool_reuses_k_tracks_drawn_from_the_seed():
    venv = league.make_vector_env(num_envs=4, track_pool=3, max_episode_steps=20)
    obs, _ = venv.reset(seed=7)
    pool = list(venv._pool)
    for k, track in enumerate(pool):
        env = league.MicroRacerEnv()
        env.reset(seed=7 + k)
        assert env.track == track
    seen = set()
    for _ in range(100):
        obs, *_ = venv.step(drive(obs))
        seen.update(map(id, venv.tracks))
    assert seen <= set(map(id, pool)) and len(seen) == 3
    venv.reset(seed=7)
    assert venv._pool == pool


def test_render_draws_sub_env_zero_and_close_is_idempotent():
    venv = league.make_vector_env(num_envs=2, render_mode="rgb_array")
    obs, _ = venv.reset(seed=0)
    for _ in range(5):
        obs, *_ = venv.step(drive(obs))
    frame = venv.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    venv.close()
    venv.close()
    assert venv.closed


@pytest.mark.parametrize("kwargs, message", [
    ({"num_envs": 0}, "num_envs"), ({"track_pool": 0}, "track_pool"), ({"obstacles": "yes"}, "obstacles"),
    ({"autoreset_mode": "Sometimes"}, "Sometimes"), ({"render_mode": "human"}, "render_mode"),
])
def test_bad_arguments_are_clear_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        league.make_vector_env(**{"num_envs": 2, **kwargs})


def test_bad_actions_and_masks_are_clear_errors():
    venv = league.make_vector_env(num_envs=2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        venv.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="NaN"):
        venv.step(np.full((2, 2), np.nan))
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": [True, False]})


def numpy_infos(cars, truncated, names=True):
    """The infos as the vector env built them with numpy before the compiled core built them."""
    codes = cars.outcome.astype(np.int64)
    codes[truncated] = league.constants.RUNNING
    infos = {"outcome": np.array(league.constants.OUTCOMES, dtype=object)[codes]} if names else {}
    infos.update(outcome_code=codes, progress=np.array([cars.progress(c) for c in range(cars.n)]),
                 time=cars.steps_taken * cars.tstep, distance=cars.distance.copy(), speed=cars.speed.copy())
    return infos


def assert_identical(mine, theirs):
    """Same keys in the same order, same types, dtypes and values (nested dicts and object arrays too)."""
    if isinstance(theirs, tuple):
        assert type(mine) is tuple and len(mine) == len(theirs)
        for a, b in zip(mine, theirs):
            assert_identical(a, b)
    elif isinstance(theirs, dict):
        assert list(mine) == list(theirs)
        for key in theirs:
            assert_identical(mine[key], theirs[key])
    elif isinstance(theirs, np.ndarray):
        assert isinstance(mine, np.ndarray) and mine.dtype == theirs.dtype and mine.shape == theirs.shape
        if theirs.dtype == object:
            assert len(mine) == len(theirs)
            for a, b in zip(mine, theirs):
                assert_identical(a, b)
        else:
            assert mine.tobytes() == theirs.tobytes()  # bit for bit, NaN and -0.0 included
    else:
        assert type(mine) is type(theirs) and mine == theirs


def test_the_compiled_infos_are_the_numpy_ones_bit_for_bit():
    venv = league.make_vector_env(num_envs=6, max_episode_steps=30)
    obs, _ = venv.reset(seed=9)
    cars, seen = venv.cars, set()
    for _ in range(200):
        for shown in (None, np.arange(6) % 2 == 0):
            for names in (True, False):
                copy, infos = cars.observe(shown, names)
                assert_identical(infos, numpy_infos(cars, np.zeros(6, bool) if shown is None else shown, names))
                assert_identical(copy, cars.obs.copy())
        seen.update(cars.outcome.tolist())
        obs, *_ = venv.step(drive(obs))
    assert len(seen) >= 2  # running and ended cars


@pytest.mark.parametrize("mode", list(AutoresetMode))
@pytest.mark.parametrize("options", [{}, {"numeric_infos": True, "observation": "lidar"}])
def test_the_fast_step_of_every_sub_env_is_the_plain_step_bit_for_bit(mode, options):
    # step(actions) takes the compiled fast path; step(actions, moving=all True) the plain one
    fast, plain = (league.make_vector_env(num_envs=5, autoreset_mode=mode, max_episode_steps=45, **options)
                   for _ in range(2))
    results = fast.reset(seed=3), plain.reset(seed=3)
    assert_identical(*results)
    everyone, ended = np.ones(5, dtype=bool), 0
    for _ in range(250):
        actions = drive(results[0][0])
        results = fast.step(actions), plain.step(actions, moving=everyone)
        assert_identical(*results)
        done = results[0][2] | results[0][3]
        ended += done.sum()
        if mode == AutoresetMode.DISABLED and done.any():
            results = fast.reset(options={"reset_mask": done}), plain.reset(options={"reset_mask": done})
            assert_identical(*results)
    assert ended >= 10
    with pytest.raises(ValueError, match="NaN"):
        fast.step(np.full((5, 2), np.nan))
    assert_identical(fast.step(drive(results[0][0])), plain.step(drive(results[0][0]), moving=everyone))

"""league.evaluation: metrics_run (SPEC "Evaluation run") and race (SPEC "Race") with replays."""
import json

import numpy as np
import pytest

import league
from league import evaluation
from league.agents import Agent, AgentError, callable_agent, heuristic_agent, heuristic_actions, load_agent
from league.constants import TRACK_CACHE_SIZE, observation_name
from league.evaluation import (
    MetricsResult,
    episode_seeds,
    league_versions,
    load_replay,
    metrics_run,
    race,
    race_again,
    replay_track,
    result_key,
    run_episode,
    save_replay,
)
from league.options import RaceOptions
from league.track import episode_start, set_track_cache_size, track_cache_info

ALL_OFF = {"obstacles": False, "chicanes": False, "turn_limit": False, "low_speed_termination": False}


def failing_after(steps: int, name: str = "crasher"):
    """A heuristic driver whose model breaks down at its `steps`-th action (after the dry run)."""
    calls = {"n": -2}  # the dry run's two calls

    def act(obs):
        calls["n"] += 1
        if calls["n"] > steps:
            raise RuntimeError("segfault in my layer")
        return heuristic_actions(obs)

    agent = callable_agent(act, obs_dim=5, name=name)
    agent.reset_calls = lambda n=0: calls.update(n=n)
    return agent


def target_speed_driver(target: float):
    def act(obs):
        actions = heuristic_actions(obs)
        actions[:, 0] = np.where(obs[:, 4] < target, 0.5, -0.2)
        return actions

    return callable_agent(act, obs_dim=5, name=f"target {target}")


# --------------------------------------------------------------------------- metrics_run


def reference_episode(env, agent, seed):
    """SPEC's evaluation loop, written out: speeds of non-final steps summed, divided by all steps."""
    obs, _ = env.reset(seed=seed)
    steps, total, speeds = 0, 0.0, []
    while True:
        obs, reward, terminated, truncated, info = env.step(agent(obs[None])[0])
        steps, total = steps + 1, total + reward
        if terminated or truncated:
            return steps, total, sum(speeds) / steps, info["outcome"]
        speeds.append(float(obs[4]))  # the observed speed (float32)


def test_metrics_follow_the_spec_definition():
    agent = heuristic_agent()
    result = metrics_run(agent, episodes=6, seed=11)
    env = league.MicroRacerEnv()
    for episode, seed in zip(result.episodes, episode_seeds(11, 6)):
        steps, total, mean_speed, outcome = reference_episode(env, agent, seed)
        assert (episode.seed, episode.steps, episode.outcome) == (seed, steps, outcome)
        assert episode.episode_return == pytest.approx(total, abs=1e-9)
        assert episode.mean_speed == pytest.approx(mean_speed, rel=1e-6)
    assert result.completed == sum(e.outcome == "finished" for e in result.episodes)
    assert result.mean_steps == pytest.approx(np.mean([e.steps for e in result.episodes]))
    assert result.mean_return == pytest.approx(np.mean([e.episode_return for e in result.episodes]))


def test_same_agent_and_seed_give_the_same_metrics_and_another_seed_does_not():
    first = metrics_run("heuristic", episodes=8, seed=5).to_dict()
    assert metrics_run("heuristic", episodes=8, seed=5).to_dict() == first
    assert metrics_run("heuristic", episodes=8, seed=6).to_dict()["episodes"] != first["episodes"]


def test_episode_seeds_depend_only_on_run_seed_and_index():
    assert episode_seeds(3, 10)[:4] == episode_seeds(3, 4)
    assert len(set(episode_seeds(3, 1000))) == 1000
    assert episode_seeds(3, 4) != episode_seeds(4, 4)


def test_onnx_and_torchscript_exports_of_one_module_give_the_same_metrics(onnx_actor, torchscript_actor):
    by_onnx = metrics_run(load_agent(onnx_actor), episodes=20, seed=2)
    by_torchscript = metrics_run(load_agent(torchscript_actor), episodes=20, seed=2)
    assert by_onnx.completed >= 10  # the actor really drives: laps, not instant crashes
    # Runtimes differ in the last bit of a float32 matmul: identical episodes, returns within 1e-6.
    for a, b in zip(by_onnx.episodes, by_torchscript.episodes):
        assert (a.seed, a.steps, a.outcome) == (b.seed, b.steps, b.outcome)
        assert a.episode_return == pytest.approx(b.episode_return, abs=1e-6)
        assert a.mean_speed == pytest.approx(b.mean_speed, abs=1e-6)
    assert by_onnx.completed == by_torchscript.completed


def test_compact_and_lidar_heuristics_drive_identically():
    compact = metrics_run(heuristic_agent(5), episodes=10, seed=4)
    lidar = metrics_run(heuristic_agent(20), episodes=10, seed=4)
    assert compact.to_dict()["episodes"] == lidar.to_dict()["episodes"]
    assert lidar.settings["obs_dim"] == 20


def sequential(agent, seed, episodes, **options):
    """The thesis' loop: each episode alone, one agent call per step (`run_episode`)."""
    env = league.MicroRacerEnv(observation=observation_name(agent.obs_dim), **options)
    return [run_episode(env, agent, episode_seed) for episode_seed in episode_seeds(seed, episodes)]


def fails_near_walls(obs):
    """A model that raises on some observations: something close ahead (a wall or an obstacle)."""
    if (obs[:, 2] < 0.05).any():
        raise RuntimeError("segfault in my layer")
    return heuristic_actions(obs)


def nan_when_fast(obs):
    actions = heuristic_actions(obs)
    actions[obs[:, 4] > 0.27] = np.nan
    return actions


@pytest.mark.parametrize("options", [{}, ALL_OFF, {"max_episode_steps": 200}])
def test_lockstep_equals_one_episode_at_a_time_for_the_heuristic(options):
    result = metrics_run("heuristic", episodes=12, seed=7, **options)
    assert result.episodes == sequential(heuristic_agent(), 7, 12, **options)


@pytest.mark.parametrize("model, reason", [(fails_near_walls, "the model raised RuntimeError: segfault in my layer"),
                                           (nan_when_fast, "the model returned NaN or infinite actions")])
def test_a_model_failing_on_some_observations_fails_only_those_episodes(model, reason):
    agent = callable_agent(model, obs_dim=5, name="flaky")
    result = metrics_run(agent, episodes=16, seed=1)
    assert result.episodes == sequential(agent, 1, 16)  # episode by episode, bit for bit
    failed = [e for e in result.episodes if e.outcome == "dnf"]
    assert 0 < len(failed) < 16 and all(e.reason == reason for e in failed)


class DiesAtCall(Agent):
    """A heuristic driver whose process dies at its n-th call: not isolable, like a sandbox's."""

    def __init__(self, n):
        super().__init__(5, "dies")
        self.calls, self.n, self.resets = 0, n, 0

    def __call__(self, obs):
        self.calls += 1
        if self.calls == self.n:
            raise AgentError("the model's process died", isolable=False)
        return heuristic_actions(np.asarray(obs, dtype=np.float32))

    def reset(self):
        self.resets += 1


def test_an_agent_failure_fails_every_episode_it_was_asked_for():
    agent = DiesAtCall(400)
    seen = []
    result = metrics_run(agent, episodes=10, seed=1, on_episode=lambda i, e: seen.append(i))
    assert sorted(seen) == list(range(10)) and agent.resets == 1
    alone = metrics_run("heuristic", episodes=10, seed=1).episodes
    for episode, expected in zip(result.episodes, alone):
        if expected.steps < 400:  # ended before the failing call
            assert episode == expected
        else:
            assert (episode.outcome, episode.steps, episode.reason) == ("dnf", 399, "the model's process died")


def test_an_agent_that_cannot_reset_fails_every_episode():
    class NoReset(DiesAtCall):
        def reset(self):
            raise AgentError("the sandbox did not start")

    result = metrics_run(NoReset(10**6), episodes=3, seed=1)
    assert [(e.outcome, e.steps, e.reason) for e in result.episodes] == [("dnf", 0, "the sandbox did not start")] * 3


def test_truncated_episodes_are_timeouts():
    result = metrics_run("heuristic", episodes=2, seed=0, max_episode_steps=25)
    assert [(e.outcome, e.steps) for e in result.episodes] == [("timeout", 25)] * 2


def test_result_converts_to_json_and_table_and_back():
    result = metrics_run("heuristic", episodes=4, seed=9, obstacles=False)
    data = json.loads(json.dumps(result.to_dict()))
    assert set(data) == {"episodes", "completed", "episodes_total", "mean_return", "mean_steps", "mean_speed",
                         "settings"}
    assert set(data["episodes"][0]) == {"seed", "steps", "return", "mean_speed", "outcome", "reason"}
    assert data["settings"]["env_options"]["obstacles"] is False and data["settings"]["seed"] == 9
    assert MetricsResult.from_dict(data).to_dict() == data
    table = result.table(per_episode=True)
    assert f"completed    {result.completed} / 4" in table and "options: chicanes, turn limit" in table


def test_a_result_records_what_produced_it_and_its_key_tells_what_compares():
    result = metrics_run("heuristic", episodes=2, seed=9, obstacles=False, max_episode_steps=50)
    versions = {"physics": league.constants.PHYSICS_VERSION, "track_format": league.constants.TRACK_FORMAT_VERSION,
                "package": league.__version__}
    assert result.settings["versions"] == league_versions() == versions
    key = result.settings["result_key"]
    assert key == result_key(9, 2, {"obstacles": False, "max_episode_steps": 50}) and len(key) == 16
    assert "  simulator    physics 1, track format 1 (league " in result.table()
    assert f"  result key   {key} (results with the same key compare)" in result.table()
    # the same settings written otherwise, and another package release, share the key
    assert result_key(9, 2, {"obstacles": False, "max_episode_steps": 50, "chicanes": True, "track_width": 0.04}) == \
        result_key(9, 2, {"obstacles": False, "max_episode_steps": 50}, {**versions, "package": "9.9"}) == key
    assert result_key(0, 100, {"track_width": 0.05}) == result_key(0, 100, {"track_width": 0.050000})
    # anything that changes the figures changes it
    others = [result_key(10, 2, {"obstacles": False, "max_episode_steps": 50}),
              result_key(9, 3, {"obstacles": False, "max_episode_steps": 50}),
              result_key(9, 2, {"max_episode_steps": 50}),
              result_key(9, 2, {"obstacles": False, "max_episode_steps": 50}, {**versions, "physics": 2}),
              result_key(9, 2, {"obstacles": False, "max_episode_steps": 50}, {**versions, "track_format": 2})]
    assert len({key, *others}) == 6


def test_observation_follows_the_agent():
    with pytest.raises(ValueError, match="follows the agent's obs_dim"):
        metrics_run("heuristic", episodes=1, observation="lidar")


def test_heuristic_fidelity_all_options_on():
    """SPEC: 133 / 150 laps, mean speed 0.267 on the reference; tolerance of the simulator issue."""
    result = metrics_run("heuristic", episodes=150, seed=0)
    assert 0.80 <= result.completed / 150 <= 0.95
    assert 0.25 <= result.mean_speed <= 0.28


def test_heuristic_fidelity_all_options_off():
    """SPEC: 150 / 150 laps, mean speed 0.261 on the reference."""
    result = metrics_run("heuristic", episodes=150, seed=0, **ALL_OFF)
    assert result.completed / 150 >= 0.97
    assert 0.25 <= result.mean_speed <= 0.28


# --------------------------------------------------------------------------- race


@pytest.fixture(scope="module")
def ten_car_race():
    agents = [target_speed_driver(t) for t in np.linspace(0.18, 0.3, 10)]
    return agents, race(agents, seed=1)


def test_classification_orders_finishers_by_time_then_others_by_distance(ten_car_race):
    _, result = ten_car_race
    rows = result.classification
    assert [r["position"] for r in rows] == list(range(1, 11))
    finishers = [r for r in rows if r["outcome"] == "finished"]
    others = rows[len(finishers):]
    assert len(finishers) >= 5
    assert [r["time"] for r in finishers] == sorted(r["time"] for r in finishers)
    assert all(r["outcome"] != "finished" for r in others)
    assert [r["distance"] for r in others] == sorted((r["distance"] for r in others), reverse=True)
    assert set(rows[0]) == {"car", "name", "position", "outcome", "time", "distance", "reason"}


def test_finish_times_are_interpolated_inside_the_step(ten_car_race):
    _, result = ten_car_race
    for row in result.classification:
        if row["outcome"] == "finished":
            steps = len(result.cars[int(row["car"][4:])].x) - 1
            assert (steps - 1) * 0.04 < row["time"] <= steps * 0.04


def test_race_re_run_from_its_seed_reproduces_positions_exactly(ten_car_race):
    agents, result = ten_car_race
    again = race_again(result.replay, agents)
    for car, car_again in zip(result.cars, again.cars):
        assert car.x == car_again.x and car.y == car_again.y and car.heading == car_again.heading
    assert again.replay == result.replay


def test_replay_round_trips_and_stays_small(ten_car_race, tmp_path):
    _, result = ten_car_race
    path = save_replay(result, tmp_path / "race.json")
    assert path.stat().st_size < 500_000  # 10 cars, about 30 s of racing
    replay = load_replay(path)
    assert replay == json.loads(json.dumps(result.replay))
    assert replay_track(replay) == league.Track.from_dict(result.replay["track"])
    assert replay["versions"] == league_versions()  # what raced it
    car = replay["cars"][3]
    assert len(car["x"]) == len(car["acc"]) + 1  # the start, then one state per action
    np.testing.assert_allclose(car["x"], result.cars[3].x, atol=1e-5)


def test_replay_files_are_checked(tmp_path):
    (tmp_path / "other.json").write_text(json.dumps({"format": "something-else"}))
    (tmp_path / "future.json").write_text(json.dumps({"format": "microracer-replay", "version": 99}))
    with pytest.raises(ValueError, match="not a MicroRacer replay"):
        load_replay(tmp_path / "other.json")
    with pytest.raises(ValueError, match="version 99"):
        load_replay(tmp_path / "future.json")


def test_a_failing_agent_is_a_dnf_for_its_car_only():
    alone = race(["heuristic"], seed=1)
    result = race([heuristic_agent(), failing_after(30)], seed=1)
    crasher = next(r for r in result.classification if r["car"] == "car_1")
    assert crasher["outcome"] == "dnf" and "segfault in my layer" in crasher["reason"]
    assert crasher["time"] == pytest.approx(30 * 0.04)
    assert len(result.cars[1].x) == 31  # the car stopped where its agent failed
    assert result.cars[0].x == alone.cars[0].x  # the other car raced on, undisturbed
    assert result.classification[0]["car"] == "car_0"


def test_the_race_track_is_the_track_of_an_episode_with_that_seed():
    env = league.MicroRacerEnv()
    env.reset(seed=21)
    assert replay_track(race(["heuristic"], seed=21).replay) == env.track


def test_a_race_on_a_given_track_replays_on_that_track():
    env = league.MicroRacerEnv()
    env.reset(seed=8)
    result = race(["heuristic"], seed=3, track=env.track, initial_speed=0.2)
    assert replay_track(result.replay) == env.track and result.cars[0].speed[0] == 0.2
    assert race_again(result.replay, ["heuristic"]).cars[0].x == result.cars[0].x


def test_compact_and_lidar_agents_race_together():
    result = race(["heuristic", "heuristic-lidar"], seed=1)
    assert result.replay["observation"] == "lidar"
    assert result.cars[0].x == result.cars[1].x  # the compact view of lidar is the compact observation


def test_names_are_unique_and_checked():
    assert race(["heuristic", "heuristic"], seed=0, max_episode_steps=5).names == ["heuristic #1", "heuristic #2"]
    assert race(["heuristic"], seed=0, names=["Ada"], max_episode_steps=5).names == ["Ada"]
    with pytest.raises(ValueError, match="2 names for 1 agents"):
        race(["heuristic"], names=["a", "b"])
    with pytest.raises(AgentError):
        race(["missing.onnx"])


# --------------------------------------------------------------------------- the track cache


def test_episode_starts_are_those_of_a_seeded_reset_and_are_cached():
    options = RaceOptions(obstacles=False, track_width=0.05)
    track, speed = episode_start(123, options)
    env = league.MicroRacerEnv(obstacles=False, track_width=0.05)
    env.reset(seed=123)
    assert (track, speed) == (env.track, env.cars.speed[0])
    assert episode_start(123, options)[0] is track  # kept: the map is not derived again
    assert episode_start(123, RaceOptions(observation="lidar", obstacles=False, track_width=0.05))[0] is track
    assert episode_start(123, RaceOptions())[0] != track  # other track options: another track


def test_the_track_cache_is_bounded_and_serves_every_evaluation():
    try:
        set_track_cache_size(4)
        first = metrics_run("heuristic", episodes=3, seed=2)
        assert track_cache_info().misses == 3 and track_cache_info().currsize == 3
        assert metrics_run("heuristic-lidar", episodes=3, seed=2).episodes == first.episodes
        assert track_cache_info().hits == 3
        metrics_run("heuristic", episodes=3, seed=9)
        assert track_cache_info().currsize == 4  # least recently used starts went out
    finally:
        set_track_cache_size(TRACK_CACHE_SIZE)


def test_an_evaluation_is_the_same_bit_for_bit_with_and_without_the_track_cache():
    """Issue 33: every evaluation of an assignment shares its tracks (a worker's cache); its results
    are those of drawing every track again, to the last bit."""
    options = {"n_obstacles": 8, "track_width": 0.05}
    try:
        set_track_cache_size(0)  # none kept: each episode draws its track
        drawn = metrics_run("heuristic", episodes=12, seed=33, **options).to_dict()
        set_track_cache_size(TRACK_CACHE_SIZE)
        first = metrics_run("heuristic", episodes=12, seed=33, **options).to_dict()
        shared = metrics_run("heuristic", episodes=12, seed=33, **options).to_dict()
        assert track_cache_info().hits == 12  # the second run drew none
    finally:
        set_track_cache_size(TRACK_CACHE_SIZE)
    assert drawn == first == shared
    assert len({e["steps"] for e in drawn["episodes"]}) > 1  # different tracks, compared episode by episode


def test_long_runs_go_in_lockstep_chunks_with_the_same_results(monkeypatch):
    expected = metrics_run("heuristic", episodes=7, seed=4)
    monkeypatch.setattr(evaluation, "LOCKSTEP_EPISODES", 3)  # bounds the maps alive at once
    seen = []
    result = metrics_run("heuristic", episodes=7, seed=4, on_episode=lambda i, e: seen.append((i, e)))
    assert result.episodes == expected.episodes
    assert sorted(seen, key=lambda pair: pair[0]) == list(enumerate(expected.episodes))

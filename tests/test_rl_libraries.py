"""The envs driven by the RL libraries students use, unmodified (issue 15), and the examples/ scripts.

Each test here once failed against a third-party client; the trainings are smoke-sized.
"""
import importlib.util
import math
from pathlib import Path

import gymnasium as gym
import imageio_ffmpeg
import numpy as np
import torch
from gymnasium.wrappers import AddRenderObservation, RecordVideo

import league
from league.agents import heuristic_actions, load_agent
from league.constants import OUTCOMES
from league.evaluation import OUTCOME_TEXT, MetricsResult, episode_seeds

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, *args: str) -> dict:
    """examples/<name>'s main(args), what `python examples/<name> args...` runs, in this process (imports
    are shared); its result: the figures it prints."""
    spec = importlib.util.spec_from_file_location(f"examples.{Path(name).stem}", EXAMPLES / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main(list(args))


def assert_evaluated(evaluation: MetricsResult, episodes: int) -> None:
    """A metrics_run of `episodes` episodes on the seeds of seed 0: each one driven for some steps to an
    outcome, with a finite return and speed."""
    assert [e.seed for e in evaluation.episodes] == episode_seeds(0, episodes)
    for episode in evaluation.episodes:
        assert episode.steps > 0 and episode.outcome in OUTCOME_TEXT
        assert math.isfinite(episode.episode_return) and math.isfinite(episode.mean_speed)


def test_record_video_writes_one_file_per_episode_across_tracks(tmp_path):
    env = gym.make("league/MicroRacer-v0", render_mode="rgb_array", max_episode_steps=12)
    env = RecordVideo(env, str(tmp_path), episode_trigger=lambda episode: True, disable_logger=True)
    for seed in range(3):  # three tracks, three episodes
        env.reset(seed=seed)
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(np.array([0.1, 0.0], dtype=np.float32))
            done = terminated or truncated
    env.close()
    videos = sorted(tmp_path.glob("*.mp4"))
    assert len(videos) == 3
    for video in videos:
        assert next(imageio_ffmpeg.read_frames(str(video)))["size"] == (650, 650)


def test_add_render_observation_gives_observations_in_its_space_on_every_track():
    env = AddRenderObservation(gym.make("league/MicroRacer-v0", render_mode="rgb_array"), render_only=False)
    assert env.observation_space["pixels"].shape == league.MicroRacerEnv.metadata["render_frame_shape"]
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs)
        obs, *_ = env.step(np.array([0.1, 0.0], dtype=np.float32))
        assert env.observation_space.contains(obs)


def test_gymnasium_vector_envs_and_stable_baselines3_env_checker():
    from stable_baselines3.common.env_checker import check_env

    check_env(gym.make("league/MicroRacer-v0"))
    vector = gym.make_vec("league/MicroRacer-v0", num_envs=2, vectorization_mode="sync")
    obs, _ = vector.reset(seed=0)
    obs, *_ = vector.step(np.zeros((2, 2), dtype=np.float32))
    assert obs.shape == (2, 5) and vector.spec.max_episode_steps == league.constants.MAX_EPISODE_STEPS


def test_example_sb3_ppo_single_car(tmp_path):
    result = run_example("sb3_ppo.py", "--timesteps", "256", "--envs", "2", "--episodes", "2", "--save",
                         str(tmp_path / "ppo.zip"))
    assert result["timesteps"] >= 256  # whole rollouts: SB3 trains to the end of the one that crosses it
    assert_evaluated(result["evaluation"], episodes=2)
    assert (tmp_path / "ppo.zip").stat().st_size > 0


def test_example_sb3_ppo_multi_car_through_supersuit():
    result = run_example("sb3_ppo_multicar.py", "--timesteps", "256", "--cars", "4", "--races", "1")
    assert result["timesteps"] >= 256
    classification = result["race"].classification
    assert sorted(row["name"] for row in classification) == ["heuristic", "sb3-ppo-shared"]
    assert sorted(row["position"] for row in classification) == [1, 2]
    for row in classification:  # each car drove until its outcome
        assert row["outcome"] in OUTCOME_TEXT and row["time"] > 0 and math.isfinite(row["distance"])


def test_example_cleanrl_ppo_on_the_vector_env(tmp_path):
    result = run_example("cleanrl_ppo.py", "--timesteps", "1024", "--envs", "4", "--rollout", "64", "--episodes", "2",
                         "--save", str(tmp_path / "actor.onnx"))
    assert (result["updates"], result["timesteps"]) == (4, 1024)  # 1024 steps: 4 rollouts of 64 steps of 4 cars
    assert math.isfinite(result["rollout_reward"])
    assert_evaluated(result["evaluation"], episodes=2)
    assert result["actor"] == tmp_path / "actor.onnx"
    actions = load_agent(result["actor"])(np.zeros((3, 5), dtype=np.float32))  # the exported actor drives
    assert actions.shape == (3, 2) and np.all(np.abs(actions) <= 1)


def test_example_torchrl_rollouts():
    # one worker process: each imports the example's own imports (torch, torchrl) again, as spawn does
    result = run_example("torchrl_rollouts.py", "--steps", "200", "--envs", "1")
    single = result["gym_env"]
    assert single["cars"] == 1 and 0 < single["steps"] <= 200
    assert len(single["returns"]) == 1 and math.isfinite(single["returns"][0])
    assert len(single["progress"]) == 1 and 0 < single["progress"][0] <= 1  # the heuristic driver moves on
    race = result["race"]
    assert 0 < race["steps"] <= 200 and race["state_shape"][0] == race["steps"]
    assert len(race["outcomes"]) == 3 and set(race["outcomes"]) <= set(OUTCOMES)


def heuristic_module(key="observation"):
    """SPEC's driver as torchrl's policy (it keeps the cars on the road)."""
    from tensordict.nn import TensorDictModule

    def drive(observation: torch.Tensor) -> torch.Tensor:
        flat = observation.reshape(-1, observation.shape[-1]).numpy()
        return torch.as_tensor(heuristic_actions(flat)).reshape(*observation.shape[:-1], 2)

    return TensorDictModule(drive, in_keys=[key], out_keys=["action"])


def test_torchrl_vectorized_gym_env_steps_as_the_native_vector_env():
    from torchrl.envs.libs.gym import GymEnv

    # "league:": its worker processes start fresh (spawn); Gymnasium imports league there before making the env
    env = GymEnv("league:league/MicroRacer-v0", num_envs=3, numeric_infos=True, max_episode_steps=10)
    env.set_seed(5)  # resets sub-env i with seed 5 + i; the rollout's reset starts their next episodes
    rollout = env.rollout(25, heuristic_module(), break_when_any_done=False)  # through the time limit
    env.close()
    assert rollout.batch_size == (3, 25)
    native = league.make_vector_env(num_envs=3, max_episode_steps=10)
    native.reset(seed=5)
    obs, _ = native.reset()
    np.testing.assert_array_equal(rollout["observation"][:, 0].numpy(), obs)
    for t in range(10):
        obs, reward, terminated, truncated, infos = native.step(rollout["action"][:, t].numpy())
        np.testing.assert_array_equal(rollout["next", "reward"][:, t, 0].numpy(), reward.astype(np.float32))
        np.testing.assert_array_equal(rollout["next", "truncated"][:, t, 0].numpy(), truncated)
        if t < 9:  # at the end, torchrl's "next" holds its placeholder (zeros): it resets at once
            np.testing.assert_array_equal(rollout["next", "observation"][:, t].numpy(), obs)
            for key in ("outcome_code", "progress", "time", "distance", "speed"):
                np.testing.assert_array_equal(rollout["next", key][:, t].numpy(), infos[key])
    assert truncated.all()
    assert (rollout["time"][:, 10] == 0).all() and (rollout["next", "time"][:, 10] > 0).all()  # new episodes


def test_torchrl_default_info_dict_reader_reads_the_infos():
    from torchrl.envs import default_info_dict_reader
    from torchrl.envs.libs.gym import GymEnv

    env = GymEnv("league/MicroRacer-v0")
    env.set_info_dict_reader(default_info_dict_reader(["outcome_code", "progress", "speed"]))
    env.set_seed(0)
    rollout = env.rollout(20, heuristic_module())
    single = league.MicroRacerEnv()
    single.reset(seed=0)
    single.reset()
    for t in range(20):
        info = single.step(rollout["action"][t].numpy())[-1]
        assert [rollout["next", key][t].item() for key in ("outcome_code", "progress", "speed")] == [
            info["outcome_code"], info["progress"], info["speed"]]
    assert rollout["next", "outcome_code"].dtype == torch.int64 and rollout["next", "progress"].dtype == torch.float64

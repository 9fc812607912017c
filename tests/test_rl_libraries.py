"""The envs driven by the RL libraries students use, unmodified (issue 15), and the examples/ scripts.

Each test here once failed against a third-party client; the trainings are smoke-sized.
"""
import runpy
import sys
from pathlib import Path

import gymnasium as gym
import imageio_ffmpeg
import numpy as np
import torch
from gymnasium.wrappers import AddRenderObservation, RecordVideo

import league
from league.agents import heuristic_actions

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, *args: str, monkeypatch) -> None:
    """Run examples/<name> as `python examples/<name> args...` does, in this process (imports are shared)."""
    monkeypatch.setattr(sys, "argv", [str(EXAMPLES / name), *args])
    runpy.run_path(str(EXAMPLES / name), run_name="__main__")


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
    assert obs.shape == (2, 5) and vector.spec.max_episode_steps == league.physics.MAX_EPISODE_STEPS


def test_example_sb3_ppo_single_car(monkeypatch, tmp_path, capsys):
    run_example("sb3_ppo.py", "--timesteps", "256", "--envs", "2", "--episodes", "2", "--save",
                str(tmp_path / "ppo.zip"), monkeypatch=monkeypatch)
    assert "sb3-ppo: 2 episodes" in capsys.readouterr().out and (tmp_path / "ppo.zip").exists()


def test_example_sb3_ppo_multi_car_through_supersuit(monkeypatch, capsys):
    run_example("sb3_ppo_multicar.py", "--timesteps", "256", "--cars", "4", "--races", "1", monkeypatch=monkeypatch)
    assert "sb3-ppo-shared" in capsys.readouterr().out


def test_example_cleanrl_ppo_on_the_vector_env(monkeypatch, tmp_path, capsys):
    run_example("cleanrl_ppo.py", "--timesteps", "1024", "--envs", "4", "--rollout", "64", "--episodes", "2",
                "--save", str(tmp_path / "actor.onnx"), monkeypatch=monkeypatch)
    assert "cleanrl-ppo: 2 episodes" in capsys.readouterr().out and (tmp_path / "actor.onnx").exists()


def test_example_torchrl_rollouts(monkeypatch, capsys):
    # one worker process: each imports the example's own imports (torch, torchrl) again, as spawn does
    run_example("torchrl_rollouts.py", "--steps", "200", "--envs", "1", monkeypatch=monkeypatch)
    out = capsys.readouterr().out
    assert "GymEnv: " in out and "PettingZooWrapper: " in out and "state (" in out


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
    native = league.vector_env(num_envs=3, max_episode_steps=10)
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

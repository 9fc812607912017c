"""The envs driven by the RL libraries students use, unmodified (issue 15), and the examples/ scripts.

Each test here once failed against a third-party client; the trainings are smoke-sized.
"""
import runpy
import sys
from pathlib import Path

import gymnasium as gym
import imageio_ffmpeg
import numpy as np
from gymnasium.wrappers import AddRenderObservation, RecordVideo

import league

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
    run_example("torchrl_rollouts.py", "--steps", "200", monkeypatch=monkeypatch)
    out = capsys.readouterr().out
    assert "GymEnv: " in out and "PettingZooWrapper: " in out and "state (" in out

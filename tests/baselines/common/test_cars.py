"""The baselines' cars (a vector env with the thesis' neutral steps) against what one
MicroRacerEnv per car, stepped in a Python loop, gives: the same transitions, car by car."""
from __future__ import annotations

import numpy as np
import pytest

from league.baselines.common.cars import NEUTRAL_ACTION, Cars, EpisodeStats
from league.env import MicroRacerEnv


class LoopedCars:
    """The reference: K MicroRacerEnv, the neutral step as the thesis describes it, one car at a time."""

    def __init__(self, n: int, seed: int, neutral_prob: float, **options):
        self.envs = [MicroRacerEnv(**options) for _ in range(n)]
        sequence = np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(sequence.spawn(1)[0])
        self.obs = np.array([env.reset(seed=int(s))[0] for env, s in zip(self.envs, sequence.generate_state(n))])
        self.neutral_prob, self.episodes = neutral_prob, []
        self.sums = [[0.0, 0, 0.0] for _ in range(n)]  # return, steps, speed of the running episode

    def step(self, actions):
        neutral = self.rng.random(len(self.envs)) < self.neutral_prob
        rows = []
        for i, env in enumerate(self.envs):
            obs, reward, terminated, truncated, info = self._env_step(i, actions[i])
            if neutral[i] and not (terminated or truncated):
                obs, reward2, terminated, truncated, info = self._env_step(i, NEUTRAL_ACTION)
                reward += reward2
            done = terminated or truncated
            rows.append((obs, np.float32(reward), terminated, truncated, done and info["outcome"] == "finished"))
            if done:
                total, steps, speed = self.sums[i]
                outcome = "timeout" if truncated and not terminated else info["outcome"]
                self.episodes.append(EpisodeStats(total, steps, outcome, speed / steps))
                self.sums[i] = [0.0, 0, 0.0]
                obs = env.reset()[0]
            self.obs[i] = obs
        return [np.array(column) for column in zip(*rows)]

    def _env_step(self, i, action):
        obs, reward, terminated, truncated, info = self.envs[i].step(action)
        self.sums[i][0] += reward
        self.sums[i][1] += 1
        if not (terminated or truncated):
            self.sums[i][2] += info["speed"]
        return obs, reward, terminated, truncated, info


@pytest.mark.parametrize("options", [{}, {"observation": "lidar", "obstacles": False, "max_episode_steps": 40}])
def test_cars_step_as_one_env_per_car_would(options):
    cars, looped = Cars(6, 3, 0.4, **options), LoopedCars(6, 3, 0.4, **options)
    np.testing.assert_array_equal(cars.reset(), looped.obs)
    rng = np.random.default_rng(0)
    for _ in range(400):
        actions = np.clip(rng.normal(0.2, 0.4, (6, 2)), -1, 1).astype(np.float32)
        for ours, theirs in zip(cars.step(actions), looped.step(actions)):
            np.testing.assert_array_equal(ours, theirs)
        np.testing.assert_array_equal(cars.obs, looped.obs)
    assert cars.pop_episodes() == looped.episodes and len(looped.episodes) > 20

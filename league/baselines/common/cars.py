"""The cars a run collects from: K single-car MicroRacer environments stepped together.

This is the baselines' environment wrapper (`Cars`), kept apart so that the way of collecting
can change here alone.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from league.baselines.common.args import CommonArgs, TrainError, env_options_of
from league.env import MicroRacerEnv

NEUTRAL_ACTION = (0.0, 0.0)  # [acceleration, turn]: keep speed and heading (thesis, section 4.1)


class EpisodeStats(NamedTuple):
    episode_return: float
    steps: int  # environment steps (a neutral action is a step of its own)
    outcome: str  # finished, off_road, wrong_direction, too_slow or timeout
    mean_speed: float  # SPEC "Evaluation run": speeds of the non-final steps / steps


class CarStep(NamedTuple):
    """What `Cars.step` returns, one row per car (arrays are fresh copies)."""

    next_obs: np.ndarray  # the observation after the action (the last one when the episode ended)
    rewards: np.ndarray
    terminated: np.ndarray  # the episode ended: finished or crashed
    truncated: np.ndarray  # out of time (max_episode_steps)
    finished: np.ndarray  # the lap is complete


class Cars:
    """K independent single-car MicroRacer environments stepped together, each on its own tracks.

    A car whose episode ends is reset at once to a new random track, so every slot always
    drives: `step` returns the true next observations (for the replay buffer) and `obs` holds
    the observations to act on next. K separate cars are as fast as the batched PettingZoo
    interface for training (a step is ~3 µs against ~2 ms of gradient updates per
    transition) and see K times more tracks, where the ParallelEnv's cars share one track
    and wait for the slowest.

    The thesis (section 4.1) "randomly performs, after a chosen action, another one composed
    of [0, 0], which keeps the same speed and direction", to loosen the agent's coupling to
    the time step: with probability ``neutral_prob`` a car's decision lasts two steps, the
    second one neutral, and the transition carries the sum of both rewards.
    """

    def __init__(self, n_cars: int, seed: int | list[int], neutral_prob: float = 0.0, **env_options):
        if n_cars < 1:
            raise TrainError(f"--envs must be at least 1, got {n_cars}")
        self.envs = [MicroRacerEnv(**env_options) for _ in range(n_cars)]
        self.n = n_cars
        self.obs_dim = self.envs[0].observation_space.shape[0]
        self.neutral_prob = neutral_prob
        sequence = np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(sequence.spawn(1)[0])
        self._seeds = [int(s) for s in sequence.generate_state(n_cars)]
        self.obs = np.zeros((n_cars, self.obs_dim), dtype=np.float32)
        self._return = np.zeros(n_cars)
        self._steps = np.zeros(n_cars, dtype=np.int64)
        self._speed_sum = np.zeros(n_cars)
        self.episodes: list[EpisodeStats] = []  # finished since the last `pop_episodes`

    def reset(self) -> np.ndarray:
        for i, env in enumerate(self.envs):
            self.obs[i] = env.reset(seed=self._seeds[i])[0]
        return self.obs.copy()

    def step(self, actions: np.ndarray) -> CarStep:
        n = self.n
        next_obs = np.empty_like(self.obs)
        rewards = np.zeros(n, dtype=np.float32)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        finished = np.zeros(n, dtype=bool)
        neutral = self.rng.random(n) < self.neutral_prob
        for i, env in enumerate(self.envs):
            obs, reward, term, trunc, info = self._env_step(i, actions[i])
            if neutral[i] and not (term or trunc):
                obs, reward2, term, trunc, info = self._env_step(i, NEUTRAL_ACTION)
                reward += reward2
            next_obs[i], rewards[i], terminated[i], truncated[i] = obs, reward, term, trunc
            if term or trunc:
                finished[i] = info["outcome"] == "finished"
                self._end_episode(i, "timeout" if trunc and not term else info["outcome"])
                self.obs[i] = env.reset()[0]
            else:
                self.obs[i] = obs
        return CarStep(next_obs, rewards, terminated, truncated, finished)

    def _env_step(self, i: int, action) -> tuple:
        obs, reward, terminated, truncated, info = self.envs[i].step(action)
        self._return[i] += reward
        self._steps[i] += 1
        if not (terminated or truncated):
            self._speed_sum[i] += info["speed"]
        return obs, reward, terminated, truncated, info

    def _end_episode(self, i: int, outcome: str) -> None:
        steps = int(self._steps[i])
        self.episodes.append(EpisodeStats(float(self._return[i]), steps, outcome, float(self._speed_sum[i]) / steps))
        self._return[i], self._steps[i], self._speed_sum[i] = 0.0, 0, 0.0

    def pop_episodes(self) -> list[EpisodeStats]:
        episodes, self.episodes = self.episodes, []
        return episodes



def make_cars(args: CommonArgs, seed_offset: int = 0) -> Cars:
    """The training cars of a run; a resumed run (`seed_offset` = its step) draws new tracks."""
    seed = args.seed if seed_offset == 0 else [args.seed, seed_offset]
    return Cars(args.envs, seed, args.neutral_prob, observation=args.observation, **env_options_of(args))

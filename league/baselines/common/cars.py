"""The cars a run collects from: K single-car MicroRacer episodes stepped together.

This is the baselines' environment wrapper (`Cars`), kept apart so that the way of collecting
can change here alone.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium.vector import AutoresetMode

from league.baselines.common.args import CommonArgs, TrainError, env_options_of
from league.vector_env import make_vector_env

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
    """K independent single-car MicroRacer episodes stepped together, each on its own tracks: a
    `league.vector_env` (one call of the compiled core per step, no Python loop over cars).

    A car whose episode ends is reset at once to a new random track (same-step autoreset), so
    every slot always drives: `step` returns the true next observations (for the replay buffer)
    and `obs` holds the observations to act on next. K separate cars see K times more tracks
    than the ParallelEnv's cars, which share one track and wait for the slowest. Car i's tracks
    and trajectory are those of `MicroRacerEnv` seeded with the run's i-th seed.

    The thesis (section 4.1) "randomly performs, after a chosen action, another one composed
    of [0, 0], which keeps the same speed and direction", to loosen the agent's coupling to
    the time step: with probability ``neutral_prob`` a car's decision lasts two steps, the
    second one neutral (only those cars move in it), and the transition carries the sum of
    both rewards.
    """

    def __init__(self, n_cars: int, seed: int | list[int], neutral_prob: float = 0.0, **env_options):
        if n_cars < 1:
            raise TrainError(f"--envs must be at least 1, got {n_cars}")
        self.env = make_vector_env(num_envs=n_cars, autoreset_mode=AutoresetMode.SAME_STEP, **env_options)
        self.n = n_cars
        self.obs_dim = self.env.single_observation_space.shape[0]
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
        self.obs = self.env.reset(seed=self._seeds)[0]
        return self.obs.copy()

    def step(self, actions: np.ndarray) -> CarStep:
        neutral = self.rng.random(self.n) < self.neutral_prob
        ended: list[tuple[int, EpisodeStats]] = []
        next_obs, rewards, terminated, truncated, outcome = self._step(actions, None, ended)
        second = neutral & ~(terminated | truncated)
        if second.any():
            obs2, rewards2, terminated2, truncated2, outcome2 = self._step(np.zeros((self.n, 2), np.float32), second,
                                                                          ended)
            next_obs[second], rewards[second] = obs2[second], rewards[second] + rewards2[second]
            terminated[second], truncated[second], outcome[second] = \
                terminated2[second], truncated2[second], outcome2[second]
        self.episodes += [stats for _, stats in sorted(ended, key=lambda item: item[0])]  # by car, as one loop would
        finished = (terminated | truncated) & (outcome == "finished")
        return CarStep(next_obs, rewards.astype(np.float32), terminated, truncated, finished)

    def _step(self, actions: np.ndarray, moving: np.ndarray | None, ended: list) -> tuple:
        """One step of the cars in `moving` (all: None): their last observations (the final one of
        an episode that ended), rewards, ends and outcomes; `obs` becomes what to act on next."""
        obs, rewards, terminated, truncated, infos = self.env.step(actions, moving)
        moved = np.ones(self.n, dtype=bool) if moving is None else moving
        done = terminated | truncated
        self._return[moved] += rewards[moved]
        self._steps[moved] += 1
        going = moved & ~done
        self._speed_sum[going] += infos["speed"][going]
        last_obs, outcome = obs.copy(), infos["outcome"].copy()
        for i in np.flatnonzero(done):
            last_obs[i], outcome[i] = infos["final_obs"][i], infos["final_info"]["outcome"][i]
            ended.append((i, self._end_episode(i, "timeout" if truncated[i] and not terminated[i] else outcome[i])))
        self.obs = np.where(moved[:, None], obs, self.obs)
        return last_obs, rewards, terminated, truncated, outcome

    def _end_episode(self, i: int, outcome: str) -> EpisodeStats:
        steps = int(self._steps[i])
        stats = EpisodeStats(float(self._return[i]), steps, str(outcome), float(self._speed_sum[i]) / steps)
        self._return[i], self._steps[i], self._speed_sum[i] = 0.0, 0, 0.0
        return stats

    def pop_episodes(self) -> list[EpisodeStats]:
        episodes, self.episodes = self.episodes, []
        return episodes


def make_cars(args: CommonArgs, seed_offset: int = 0) -> Cars:
    """The training cars of a run; a resumed run (`seed_offset` = its step) draws new tracks."""
    seed = args.seed if seed_offset == 0 else [args.seed, seed_offset]
    return Cars(args.envs, seed, args.neutral_prob, observation=args.observation, **env_options_of(args))

"""The probe set: a fixed set of realistic observations on which agents' actions are compared.

Two uploads that answer the probe set with the same actions (within a tolerance) are one policy,
whatever their files: one network exported to ONNX and to TorchScript differs by float rounding
(~2e-7), two trained agents by far more (0.8 to 2: benchmarks/bench_integrity.py). The server
records each submission's actions on it in the sandbox that validates it
(league.server.sandbox.validation) and its integrity report
compares them (league.server.course.integrity).

The observations are drawn once from PROBE_SEED on real tracks: a driver with a target speed of
its own per track and noisy steering goes round, and every SAMPLE_EVERY-th observation is kept,
so the set holds straights, curves, obstacles ahead, slow and fast cars. The compact set is the
lidar set's compact form (the same states). A new simulator (tracks, physics) may draw another
set: its `probe_key` names it, and only actions on the same set are compared.

That public set is known to anyone who reads this file, so an agent can answer it differently
from the policy it copies. Each assignment therefore has a **secret set** too
(`secret_probe_observations`): the same drawing on the assignment's private tracks (their episode
seeds and options) with a driver whose noise comes from the private seed, so nobody can compute
it before the private seed is published. Only the server draws it, in the sandboxed probe jobs
an instructor queues (league.server.jobs.probe); its key, a hash of its values, names it.
"""
from __future__ import annotations

import functools
import hashlib
import itertools
from dataclasses import dataclass

import numpy as np

from league.agents import compact_from_lidar, heuristic_actions
from league.constants import COMPACT_DIM, LIDAR_DIM

PROBE_SEED = 20260401
PROBES = 64  # observations: enough to tell trained agents apart, small to store (512 bytes of actions)
SAMPLE_EVERY = 9  # steps between kept observations (consecutive ones are near-duplicates)
MAX_STEPS = 300  # per track, so the set spans several tracks
SECRET_PROBES = 192  # a secret set's observations, picked at random from its visits' (1.5 kB of actions)
SECRET_VISITS = 64  # at most, drives round the private tracks (in turn), each at a target speed of its own
STEER_NOISE = 0.35  # standard deviation added to the steering, which takes the car off the ideal line
SECRET_SALT = 0x1A7E6B17  # keeps a secret set's driver noise apart from the private tracks' own draws


@dataclass(frozen=True)
class Probe:
    """An agent's answer to the probe set `key`: its actions (probe_actions_bytes), or why it gave none."""

    key: str
    actions: bytes | None
    error: str | None = None


def probe_observations(obs_dim: int) -> np.ndarray:
    """The probe set for agents of `obs_dim` (5 or 20 values), float32 (PROBES, obs_dim) (a copy)."""
    if obs_dim not in (COMPACT_DIM, LIDAR_DIM):
        raise ValueError(f"no probe set for {obs_dim} observation values (5 or 20)")
    lidar = _lidar_probes()
    return lidar.copy() if obs_dim == LIDAR_DIM else compact_from_lidar(lidar)


@functools.lru_cache(maxsize=2)
def probe_key(obs_dim: int) -> str:
    """Names the probe set (16 hex digits of the sha256 of its values)."""
    return observations_key(probe_observations(obs_dim))


def secret_probe_observations(private: dict, obs_dim: int) -> np.ndarray:
    """An assignment's secret probe set for agents of `obs_dim`: drawn on its private tracks
    (`private`: Assignment.private_settings(), {"seed", "episodes", "env_options"})."""
    if obs_dim not in (COMPACT_DIM, LIDAR_DIM):
        raise ValueError(f"no probe set for {obs_dim} observation values (5 or 20)")
    lidar = _secret_lidar_probes(int(private["seed"]), int(private["episodes"]),
                                 tuple(sorted(dict(private.get("env_options") or {}).items())))
    return lidar.copy() if obs_dim == LIDAR_DIM else compact_from_lidar(lidar)


def observations_key(observations: np.ndarray) -> str:
    """Names a probe set (16 hex digits of the sha256 of its values): reveals nothing of them."""
    return hashlib.sha256(np.ascontiguousarray(observations, dtype=np.float32).tobytes()).hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def _lidar_probes() -> np.ndarray:  # drawn once per process (~0.2 s)
    rng = np.random.default_rng(PROBE_SEED)
    return _drive(rng, (int(rng.integers(2**31)) for _ in itertools.count()), {})


@functools.lru_cache(maxsize=256)  # ~5 kB each: a server's assignments
def _secret_lidar_probes(seed: int, episodes: int, env_options: tuple) -> np.ndarray:
    from league.evaluation import episode_seeds

    tracks = episode_seeds(seed, max(episodes, 1))
    rng = np.random.default_rng(np.random.SeedSequence([seed, SECRET_SALT]))  # not the tracks' own stream
    visited = _drive(rng, itertools.islice(itertools.cycle(tracks), SECRET_VISITS), dict(env_options),
                     count=2 * SECRET_PROBES)  # then half of them at random: any speed, any point of a lap
    keep = np.sort(rng.choice(len(visited), size=min(SECRET_PROBES, len(visited)), replace=False))
    return visited[keep]


def _drive(rng: np.random.Generator, track_seeds, env_options: dict, count: int = PROBES) -> np.ndarray:
    """`count` observations (fewer if the tracks run out) kept every SAMPLE_EVERY steps of a noisy
    driver, at most MAX_STEPS per visit of the tracks `track_seeds` gives, each visit with a target
    speed of its own."""
    from league.env import MicroRacerEnv  # the simulator, only when a probe set is first needed

    env, kept, seen = MicroRacerEnv(**{**env_options, "observation": "lidar"}), [], set()
    for track in track_seeds:
        if len(kept) == count:
            break
        obs, _ = env.reset(seed=track)
        target_speed = rng.uniform(0.1, 0.5)
        for step in range(MAX_STEPS):
            if step % SAMPLE_EVERY == 0 and (step or track not in seen):  # a track's start: kept once
                kept.append(obs)
            action = heuristic_actions(compact_from_lidar(obs[None]))[0]
            action[0] = 0.5 if obs[-1] < target_speed else -0.3
            action[1] += rng.normal(0, STEER_NOISE)
            obs, _, terminated, truncated, _ = env.step(np.clip(action, -1, 1))
            if terminated or truncated or len(kept) == count:
                break
        seen.add(track)
    return np.asarray(kept, dtype=np.float32)


def probe_actions_bytes(actions: np.ndarray) -> bytes:
    """Actions on a probe set as stored: float32 (observations, 2), row-major (PROBES of them for
    the public set, up to SECRET_PROBES for a secret one)."""
    actions = np.asarray(actions, dtype=np.float32)
    if actions.ndim != 2 or actions.shape[1] != 2 or not 0 < len(actions) <= max(PROBES, SECRET_PROBES):
        raise ValueError(f"expected up to {SECRET_PROBES} actions of 2 values, got shape {actions.shape}")
    return actions.tobytes()


def probe_actions_from_bytes(data: bytes) -> np.ndarray:
    return np.frombuffer(data, dtype=np.float32).reshape(-1, 2)

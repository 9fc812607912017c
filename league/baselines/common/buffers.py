"""The replay buffer of the off-policy baselines."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch


class ReplayBatch(NamedTuple):
    observations: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor  # (batch,)
    next_observations: torch.Tensor
    dones: torch.Tensor  # (batch,) 1.0 where the next state is terminal (no bootstrap)


class ReplayBuffer:
    """A FIFO buffer of transitions (Lin 1992; Mnih et al. 2015), sampled uniformly."""

    def __init__(self, capacity: int, obs_dim: int, act_dim: int, seed: int):
        self.capacity = capacity
        self.observations = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.next_observations = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.actions = np.zeros((capacity, act_dim), dtype=np.float32)
        self.rewards = np.zeros(capacity, dtype=np.float32)
        self.dones = np.zeros(capacity, dtype=np.float32)
        self.pos = 0  # next slot to write
        self.size = 0
        self.rng = np.random.default_rng(seed)

    def add(self, obs: np.ndarray, actions: np.ndarray, rewards: np.ndarray, next_obs: np.ndarray,
            dones: np.ndarray) -> None:
        """Store a batch of transitions (one per car)."""
        for k in range(len(obs)):
            p = self.pos
            self.observations[p], self.actions[p], self.rewards[p] = obs[k], actions[k], rewards[k]
            self.next_observations[p], self.dones[p] = next_obs[k], dones[k]
            self.pos = (p + 1) % self.capacity
            self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int) -> ReplayBatch:
        idx = self.rng.integers(0, self.size, size=batch_size)
        return ReplayBatch(*(torch.from_numpy(a[idx]) for a in (self.observations, self.actions, self.rewards,
                                                                  self.next_observations, self.dones)))

    def state_dict(self) -> dict:
        n = self.size
        return {"observations": torch.from_numpy(self.observations[:n].copy()),
                "next_observations": torch.from_numpy(self.next_observations[:n].copy()),
                "actions": torch.from_numpy(self.actions[:n].copy()),
                "rewards": torch.from_numpy(self.rewards[:n].copy()),
                "dones": torch.from_numpy(self.dones[:n].copy()),
                "pos": self.pos, "rng": self.rng.bit_generator.state}

    def load_state_dict(self, state: dict) -> None:
        n = len(state["rewards"])
        for name in ("observations", "next_observations", "actions", "rewards", "dones"):
            getattr(self, name)[:n] = state[name].numpy()
        self.size, self.pos = n, int(state["pos"])
        self.rng.bit_generator.state = state["rng"]


"""Deep Deterministic Policy Gradient (DDPG) for MicroRacer.

Lillicrap et al., "Continuous control with deep reinforcement learning", 2016
(https://arxiv.org/abs/1509.02971). As in Stable-Baselines3, DDPG is TD3 with its three tricks
switched off, and this module reuses `td3.py` rather than copying it: `Args` subclasses
`td3.Args` with one critic (`n_critics=1`: no clipped double-Q), no policy delay
(`policy_frequency=1`) and no target policy smoothing (`policy_noise=0`); the learner is
`td3.TD3`, trained by the off-policy loop of `common/off_policy.py`. What is DDPG's own here are the thesis' networks
(section 4.1): a two-tower actor and a critic that processes the state and the action apart
before joining them.
Thesis: section 1.7.1 (algorithm), section 4.1 (networks), table 4.1 (hyperparameters).

    league train ddpg --steps 50000 --seed 1 --out runs/ddpg-1
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from league.baselines import td3
from league.baselines.common.args import LR_FINAL_HELP, obs_dim_of, option
from league.baselines.common.networks import ObservationNormalizer, mlp
from league.baselines.common.run import Run


@dataclass
class Args(td3.Args):
    policy_frequency: int = option(1, "update the actor every this many critic updates (DDPG: every one)")
    policy_noise: float = option(0.0, "no target policy smoothing in DDPG")
    n_critics: int = option(1, "one critic, no clipped double-Q")
    lr_final_fraction: float = option(0.0, LR_FINAL_HELP)
    hidden: int = option(32, "units of the hidden layers of each actor tower (section 4.1)")


class Actor(nn.Module):
    """Two towers of two hidden layers of 32 ReLU units with a tanh output: one computes the
    acceleration, the other the direction (section 4.1)."""

    def __init__(self, obs_dim: int, hidden: int = 32):
        super().__init__()
        self.obs_dim = obs_dim
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.acceleration = mlp([obs_dim, hidden, hidden, 1], output_activation=nn.Tanh)
        self.direction = mlp([obs_dim, hidden, hidden, 1], output_activation=nn.Tanh)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        obs = self.obs_norm(obs)
        return torch.cat([self.acceleration(obs), self.direction(obs)], 1)


class QNetwork(nn.Module):
    """Q(s, a): the state through 16 then 32 ReLU units, the action through 32, joined and
    through two layers of 64 ReLU units (section 4.1; used by DDPG and DDPG2)."""

    def __init__(self, obs_dim: int):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.state_path = mlp([obs_dim, 16, 32], output_activation=nn.ReLU)
        self.action_path = mlp([td3.ACT_DIM, 32], output_activation=nn.ReLU)
        self.head = mlp([64, 64, 64, 1])

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.head(torch.cat([self.state_path(self.obs_norm(obs)), self.action_path(action)], 1)).squeeze(1)


def make_policy(args: Args) -> Actor:
    return Actor(obs_dim_of(args), args.hidden)


def make_learner(args: Args) -> td3.TD3:
    obs_dim = obs_dim_of(args)
    return td3.TD3(Actor(obs_dim, args.hidden), [QNetwork(obs_dim)], args)


def train(args: Args, run: Run) -> dict:
    return td3.train(args, run, make=make_learner)

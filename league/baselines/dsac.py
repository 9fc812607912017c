"""Distributional Soft Actor-Critic (DSAC) for MicroRacer.

Duan, Guan, Li et al., "Distributional Soft Actor-Critic: Off-Policy Reinforcement Learning
for Addressing Value Estimation Errors", IEEE TNNLS 2021 (https://arxiv.org/abs/2001.02811).
SAC (`sac.py`) with its clipped double-Q replaced by one critic that returns a Gaussian
distribution of the soft return, Z(s, a) ~ N(Q(s, a), σ(s, a)²), learnt by maximum likelihood
of the distributional Bellman target (thesis eq. 1.21), with the paper's two safeguards:
σ is bounded below by σ_min and the sampled target is clipped to Q(s, a) ± b.
Thesis: section 1.7.5 (algorithm, figure 1.7), section 4.1 (networks), table 4.1.

    league train dsac --steps 50000 --seed 1 --out runs/dsac-1
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from league.baselines.common.args import LR_FINAL_HELP, CommonArgs, obs_dim_of, option
from league.baselines.common import off_policy
from league.baselines.common.networks import (ObservationNormalizer, adam, fit_normalizers, mlp,
                                               polyak_update)
from league.baselines.common.run import Run
from league.baselines.common.off_policy import OffPolicyLearner
from league.baselines.sac import ACT_DIM, Actor, DeterministicActor


@dataclass
class Args(CommonArgs):
    gamma: float = option(0.99, "discount factor (table 4.1)")
    tau: float = option(0.005, "target network update rate (table 4.1)")
    buffer_size: int = option(50_000, "replay buffer size (table 4.1)")
    batch_size: int = option(64, "mini-batch size (table 4.1)")
    policy_lr: float = option(1e-3, "actor learning rate (table 4.1)")
    q_lr: float = option(1e-3, "critic and temperature learning rate (table 4.1)")
    lr_final_fraction: float = option(0.1, LR_FINAL_HELP)
    learning_starts: int = option(1_000, "steps of uniformly random actions before learning starts")
    policy_frequency: int = option(2, "update the actor, the temperature and the targets every this many critic "
                                      "updates (table 4.1: 2)")
    min_sigma: float = option(1.0, "lower bound σ_min of the critic's standard deviation (table 4.1)")
    td_bound: float = option(10.0, "the sampled target is clipped to Q(s, a) ± td_bound (table 4.1: critic difference "
                                   "boundary)")
    alpha: float = option(0.2, "entropy coefficient: the initial value when autotuned, else fixed")
    autotune: bool = option(True, "tune the entropy coefficient toward the target entropy -|A| (table 4.1)")
    hidden: int = option(64, "units of the two hidden layers of the actor and the critic (section 4.1)")
    observation: str = option("lidar", "what the agent sees: 'compact' (5 numbers, as the thesis) or 'lidar' (19 rays "
                                       "+ speed)")


# --------------------------------------------------------------------------- networks (section 4.1)


class DistributionalCritic(nn.Module):
    """Z(s, a) ~ N(Q, σ²): the actor's structure on [s, a] (two hidden layers of 64 ReLU units),
    a mean and a standard deviation σ = max(softplus(·), σ_min)."""

    def __init__(self, obs_dim: int, hidden: int = 64, min_sigma: float = 1.0):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.net = mlp([obs_dim + ACT_DIM, hidden, hidden], output_activation=nn.ReLU)
        self.fc_mean = nn.Linear(hidden, 1)
        self.fc_std = nn.Linear(hidden, 1)
        self.min_sigma = min_sigma

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.net(torch.cat([self.obs_norm(obs), action], 1))
        std = F.softplus(self.fc_std(h)).clamp(min=self.min_sigma)
        return self.fc_mean(h).squeeze(1), std.squeeze(1)


def make_policy(args: Args) -> DeterministicActor:
    obs_dim = obs_dim_of(args)
    return DeterministicActor(Actor(obs_dim, args.hidden), obs_dim)


# --------------------------------------------------------------------------- the critic's target and loss


def critic_targets(rewards: torch.Tensor, dones: torch.Tensor, next_q: torch.Tensor, next_z: torch.Tensor,
                   next_log_pi: torch.Tensor, alpha: float, gamma: float) -> tuple[torch.Tensor, torch.Tensor]:
    """The soft distributional Bellman target T Z(s, a) = r + γ (Z(s', a') − α log π(a'|s')).

    Returns ``target_q``, built on the target critic's mean Q'(s', a') (the paper replaces the
    random target by its expectation in the mean's gradient, to cut its variance), and
    ``target_z``, built on a sample Z(s', a') ~ N(Q', σ'²) (for the σ gradient).
    """
    not_done = 1 - dones
    target_q = rewards + gamma * not_done * (next_q - alpha * next_log_pi)
    target_z = rewards + gamma * not_done * (next_z - alpha * next_log_pi)
    return target_q, target_z


def critic_loss(q: torch.Tensor, std: torch.Tensor, target_q: torch.Tensor, target_z: torch.Tensor,
                td_bound: float) -> torch.Tensor:
    """−log N(target | Q, σ²), split as in the paper's update of the critic (Duan et al. 2021):

        ∂/∂Q: −(target_q − Q) / σ²                          (σ held fixed)
        ∂/∂σ: −((clip(target_z, Q − b, Q + b) − Q)² / σ³ − 1 / σ)   (Q held fixed)

    The surrogate (target_q − Q)² / (2 sg(σ)²) + (z − sg(Q))² / (2σ²) + log σ has exactly
    these gradients (sg = stop-gradient).
    """
    q_fixed, std_fixed = q.detach(), std.detach()
    target_z = torch.maximum(torch.minimum(target_z, q_fixed + td_bound), q_fixed - td_bound)
    mean_term = (target_q - q) ** 2 / (2 * std_fixed ** 2)
    std_term = (target_z - q_fixed) ** 2 / (2 * std ** 2) + torch.log(std)
    return (mean_term + std_term).mean()


# --------------------------------------------------------------------------- the learner


class DSAC(OffPolicyLearner):
    """Networks, optimizers and updates of Duan et al. (2021), Algorithm 1 (thesis figure 1.7)."""

    def __init__(self, obs_dim: int, args: Args):
        self.args = args
        self.actor = Actor(obs_dim, args.hidden)
        self.actor_target = copy.deepcopy(self.actor)  # DSAC bootstraps with a target policy π_φ'
        self.qf = DistributionalCritic(obs_dim, args.hidden, args.min_sigma)
        self.qf_target = copy.deepcopy(self.qf)
        self.params = [*self.qf.parameters(), *self.actor.parameters()]
        self.target_params = [*self.qf_target.parameters(), *self.actor_target.parameters()]
        self.q_optimizer = adam(self.qf.parameters(), lr=args.q_lr)
        self.actor_optimizer = adam(self.actor.parameters(), lr=args.policy_lr)
        self.target_entropy = -float(ACT_DIM)  # table 4.1: −|A|
        self.log_alpha = torch.full((1,), math.log(args.alpha), requires_grad=True)
        self.a_optimizer = adam([self.log_alpha], lr=args.q_lr)
        self.optimizers = [self.q_optimizer, self.actor_optimizer, self.a_optimizer]
        self.alpha = args.alpha
        self._policy = DeterministicActor(self.actor, obs_dim)

    def update_critics(self, data) -> dict:
        with torch.no_grad():
            next_actions, next_log_pi = self.actor_target.get_action(data.next_observations)
            next_q, next_std = self.qf_target(data.next_observations, next_actions)
            next_z = next_q + next_std * torch.randn_like(next_std)  # Z(s', a') ~ N(Q', σ'²)
            target_q, target_z = critic_targets(data.rewards, data.dones, next_q, next_z, next_log_pi,
                                                self.alpha, self.args.gamma)
        q, std = self.qf(data.observations, data.actions)
        qf_loss = critic_loss(q, std, target_q, target_z, self.args.td_bound)
        self.q_optimizer.zero_grad()
        qf_loss.backward()
        self.q_optimizer.step()
        return {"qf_loss": qf_loss.detach(), "qf_values": q.detach().mean(), "qf_std": std.detach().mean()}

    def update_actor(self, data) -> dict:
        """As SAC with the critic's mean: J_π = E[α log π(ã|s) − Q(s, ã)]; then the temperature
        and the Polyak updates of θ' and φ'."""
        pi, log_pi = self.actor.get_action(data.observations)
        q_pi, _ = self.qf(data.observations, pi)
        actor_loss = (self.alpha * log_pi - q_pi).mean()
        self.actor_optimizer.zero_grad()
        actor_loss.backward()
        self.actor_optimizer.step()
        losses = {"actor_loss": actor_loss.detach(), "entropy": -log_pi.detach().mean()}
        if self.args.autotune:
            alpha_loss = (-self.log_alpha.exp() * (log_pi.detach() + self.target_entropy)).mean()
            self.a_optimizer.zero_grad()
            alpha_loss.backward()
            self.a_optimizer.step()
            self.alpha = self.log_alpha.exp().item()
            losses["alpha_loss"] = alpha_loss.detach()
        polyak_update(self.params, self.target_params, self.args.tau)
        return losses

    def fit_normalizers(self, observations: np.ndarray) -> None:
        fit_normalizers([self.actor, self.actor_target, self.qf, self.qf_target], observations)

    def act(self, obs: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """Actions sampled from the policy (its own noise: `rng` is not used)."""
        with torch.no_grad():
            actions, _ = self.actor.get_action(torch.from_numpy(obs))
        return actions.numpy()

    def logged(self) -> dict:
        return {"alpha": self.alpha}

    def policy(self) -> DeterministicActor:
        return self._policy

    def state_dict(self) -> dict:
        return {name: getattr(self, name).state_dict() for name in NETWORKS} | {"log_alpha": self.log_alpha.detach()}

    def load_state_dict(self, state: dict) -> None:
        for name in NETWORKS:
            getattr(self, name).load_state_dict(state[name])
        with torch.no_grad():
            self.log_alpha.copy_(state["log_alpha"])
        self.alpha = self.log_alpha.exp().item()


NETWORKS = ("actor", "actor_target", "qf", "qf_target", "q_optimizer", "actor_optimizer", "a_optimizer")


# --------------------------------------------------------------------------- training


def train(args: Args, run: Run) -> dict:
    """The shared off-policy loop (league.baselines.common.off_policy) with this learner."""
    return off_policy.train(args, run, lambda args: DSAC(obs_dim_of(args), args))

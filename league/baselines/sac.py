"""Soft Actor-Critic for MicroRacer.

Haarnoja et al., "Soft Actor-Critic: Off-Policy Maximum Entropy Deep Reinforcement Learning
with a Stochastic Actor", 2018 (https://arxiv.org/abs/1801.01290), with the automatic
temperature of "Soft Actor-Critic Algorithms and Applications", 2018
(https://arxiv.org/abs/1812.05905). Written after CleanRL's ``sac_continuous_action.py``.
Thesis: section 1.7.4 (algorithm), section 4.1 (networks), table 4.1 (hyperparameters).

    league train sac --steps 50000 --seed 1 --out runs/sac-1
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
from league.baselines.common.off_policy import ACT_DIM, OffPolicyLearner
LOG_STD_MAX = 2  # bounds of the actor's log standard deviation (CleanRL, SpinningUp)
LOG_STD_MIN = -5


@dataclass
class Args(CommonArgs):
    gamma: float = option(0.99, "discount factor (table 4.1)")
    tau: float = option(0.005, "target network update rate (table 4.1)")
    buffer_size: int = option(50_000, "replay buffer size (table 4.1)")
    batch_size: int = option(64, "mini-batch size (table 4.1)")
    policy_lr: float = option(1e-3, "actor learning rate (table 4.1)")
    q_lr: float = option(1e-3, "critic and temperature learning rate (table 4.1)")
    lr_final_fraction: float = option(1.0, LR_FINAL_HELP)
    learning_starts: int = option(1_000, "steps of uniformly random actions before learning starts")
    policy_frequency: int = option(1, "update the actor and the temperature every this many critic updates (the "
                                      "thesis: every one)")
    alpha: float = option(0.2, "entropy coefficient: the initial value when autotuned, else fixed")
    autotune: bool = option(True, "tune the entropy coefficient toward the target entropy -|A| (table 4.1)")
    hidden: int = option(64, "units of the two hidden layers of the actor and the critics (section 4.1)")
    observation: str = option("lidar", "what the agent sees: 'compact' (5 numbers, as the thesis) or 'lidar' (19 rays "
                                       "+ speed)")


# --------------------------------------------------------------------------- networks (section 4.1)


class SoftQNetwork(nn.Module):
    """Q(s, a): two hidden layers of 64 ReLU units on [s, a] (thesis: as TD3's critic)."""

    def __init__(self, obs_dim: int, hidden: int = 64):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.net = mlp([obs_dim + ACT_DIM, hidden, hidden, 1])

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([self.obs_norm(obs), action], 1)).squeeze(1)


class Actor(nn.Module):
    """π(a|s): two hidden layers of 64 ReLU units, then a mean and a log std per action;
    actions are tanh(u), u ~ N(mean, std²) (Haarnoja et al. 2018, appendix C)."""

    def __init__(self, obs_dim: int, hidden: int = 64):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.net = mlp([obs_dim, hidden, hidden], output_activation=nn.ReLU)
        self.fc_mean = nn.Linear(hidden, ACT_DIM)
        self.fc_logstd = nn.Linear(hidden, ACT_DIM)

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.net(self.obs_norm(obs))
        log_std = torch.tanh(self.fc_logstd(h))  # squashed into [LOG_STD_MIN, LOG_STD_MAX]
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (log_std + 1)
        return self.fc_mean(h), log_std

    def get_action(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A reparameterised sample a = tanh(mean + std·ε) and its log π(a|s)."""
        mean, log_std = self(obs)
        std = log_std.exp()
        u = mean + std * torch.randn_like(mean)
        log_prob = (-0.5 * ((u - mean) / std) ** 2 - log_std - 0.5 * math.log(2 * math.pi)).sum(1)
        # change of variables through tanh: log π(a|s) = log μ(u|s) − Σ log(1 − tanh²(u)),
        # with log(1 − tanh²(u)) = 2 (log 2 − u − softplus(−2u)) for stability (SpinningUp)
        log_prob -= (2 * (math.log(2) - u - F.softplus(-2 * u))).sum(1)
        return torch.tanh(u), log_prob


class DeterministicActor(nn.Module):
    """What is exported and evaluated: the mean action tanh(mean(s)), no noise."""

    def __init__(self, actor: Actor, obs_dim: int):
        super().__init__()
        self.actor = actor
        self.obs_dim = obs_dim

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        mean, _ = self.actor(obs)
        return torch.tanh(mean)


def make_policy(args: Args) -> DeterministicActor:
    """A fresh deterministic actor (`league export` loads a run's weights into it)."""
    obs_dim = obs_dim_of(args)
    return DeterministicActor(Actor(obs_dim, args.hidden), obs_dim)


# --------------------------------------------------------------------------- the learner


class SoftActorCritic(OffPolicyLearner):
    """Networks, optimizers and the updates of Haarnoja et al. (2018b), Algorithm 1."""

    def __init__(self, obs_dim: int, args: Args):
        self.args = args
        self.actor = Actor(obs_dim, args.hidden)
        self.qf1 = SoftQNetwork(obs_dim, args.hidden)
        self.qf2 = SoftQNetwork(obs_dim, args.hidden)
        self.qf1_target = copy.deepcopy(self.qf1)
        self.qf2_target = copy.deepcopy(self.qf2)
        self.q_params = [*self.qf1.parameters(), *self.qf2.parameters()]
        self.q_target_params = [*self.qf1_target.parameters(), *self.qf2_target.parameters()]
        self.q_optimizer = adam(self.q_params, lr=args.q_lr)
        self.actor_optimizer = adam(self.actor.parameters(), lr=args.policy_lr)
        self.target_entropy = -float(ACT_DIM)  # table 4.1: −|A|
        self.log_alpha = torch.full((1,), math.log(args.alpha), requires_grad=True)
        self.a_optimizer = adam([self.log_alpha], lr=args.q_lr)
        self.optimizers = [self.q_optimizer, self.actor_optimizer, self.a_optimizer]
        self.alpha = args.alpha
        self._policy = DeterministicActor(self.actor, obs_dim)

    def update_critics(self, data) -> dict:
        """J_Q = E[(Q_i(s, a) − y)²], y = r + γ (1 − d)(min_i Q_targ,i(s', ã') − α log π(ã'|s')), ã' ~ π(·|s')."""
        with torch.no_grad():
            next_state_actions, next_state_log_pi = self.actor.get_action(data.next_observations)
            qf1_next_target = self.qf1_target(data.next_observations, next_state_actions)
            qf2_next_target = self.qf2_target(data.next_observations, next_state_actions)
            min_qf_next_target = torch.min(qf1_next_target, qf2_next_target) - self.alpha * next_state_log_pi
            next_q_value = data.rewards + (1 - data.dones) * self.args.gamma * min_qf_next_target
        qf1_a_values = self.qf1(data.observations, data.actions)
        qf2_a_values = self.qf2(data.observations, data.actions)
        qf1_loss = F.mse_loss(qf1_a_values, next_q_value)
        qf2_loss = F.mse_loss(qf2_a_values, next_q_value)
        qf_loss = qf1_loss + qf2_loss
        self.q_optimizer.zero_grad()
        qf_loss.backward()
        self.q_optimizer.step()
        return {"qf1_loss": qf1_loss.detach(), "qf2_loss": qf2_loss.detach(),
                "qf1_values": qf1_a_values.detach().mean()}

    def update_actor(self, data) -> dict:
        """J_π = E[α log π(ã|s) − min_i Q_i(s, ã)], ã ~ π(·|s) reparameterised; then the
        temperature: J(α) = E[−α (log π(ã|s) + H̄)] with H̄ = −|A| (eq. 18 of the 2018b paper)."""
        pi, log_pi = self.actor.get_action(data.observations)
        min_qf_pi = torch.min(self.qf1(data.observations, pi), self.qf2(data.observations, pi))
        actor_loss = (self.alpha * log_pi - min_qf_pi).mean()
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
        return losses

    def after_update(self) -> None:
        """The critics' targets follow at every gradient step (the actor has none)."""
        polyak_update(self.q_params, self.q_target_params, self.args.tau)

    def fit_normalizers(self, observations: np.ndarray) -> None:
        fit_normalizers([self.actor, self.qf1, self.qf2, self.qf1_target, self.qf2_target], observations)

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


NETWORKS = ("actor", "qf1", "qf2", "qf1_target", "qf2_target", "q_optimizer", "actor_optimizer", "a_optimizer")


# --------------------------------------------------------------------------- training


def train(args: Args, run: Run) -> dict:
    """The shared off-policy loop (league.baselines.common.off_policy) with this learner."""
    return off_policy.train(args, run, lambda args: SoftActorCritic(obs_dim_of(args), args))

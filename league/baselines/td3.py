"""Twin Delayed DDPG (TD3) for MicroRacer.

Fujimoto, van Hoof and Meger, "Addressing Function Approximation Error in Actor-Critic
Methods", 2018 (https://arxiv.org/abs/1802.09477), after CleanRL's ``td3_continuous_action.py``.
Thesis: section 1.7.3 (algorithm), section 4.1 (networks), table 4.1 (hyperparameters).

DDPG (`ddpg.py`) and DDPG with parameter noise (`ddpg_param_noise.py`) are this file with the
three tricks removed (one critic, no delay, no target smoothing), as in Stable-Baselines3.

    league train td3 --steps 50000 --seed 1 --out runs/td3-1
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from league.baselines.common.args import LR_FINAL_HELP, CommonArgs, obs_dim_of, option
from league.baselines.common import off_policy
from league.baselines.common.networks import ObservationNormalizer, adam, fit_normalizers, mlp, polyak_update
from league.baselines.common.off_policy import ACT_DIM, OffPolicyLearner
from league.baselines.common.run import Run


@dataclass
class Args(CommonArgs):
    gamma: float = option(0.99, "discount factor (table 4.1)")
    tau: float = option(0.005, "target network update rate (table 4.1)")
    buffer_size: int = option(50_000, "replay buffer size (table 4.1)")
    batch_size: int = option(64, "mini-batch size (table 4.1)")
    learning_rate: float = option(1e-3, "actor and critic learning rate (table 4.1)")
    lr_final_fraction: float = option(1.0, LR_FINAL_HELP)
    learning_starts: int = option(1_000, "steps of uniformly random actions before learning starts")
    exploration_noise: float = option(0.1, "standard deviation of the Gaussian action noise N(0, σ) (table 4.1)")
    policy_frequency: int = option(2, "update the actor and the targets every this many critic updates (table 4.1: 2)")
    policy_noise: float = option(0.2, "standard deviation of the target policy smoothing noise (Fujimoto et al.)")
    noise_clip: float = option(0.5, "the target policy smoothing noise is clipped to ±noise_clip (table 4.1)")
    n_critics: int = option(2, "clipped double-Q: the target takes the minimum of this many critics")
    hidden: int = option(64, "units of the two hidden layers of the actor and the critics (section 4.1)")
    observation: str = option("lidar", "what the agent sees: 'compact' (5 numbers, as the thesis) or 'lidar' (19 rays "
                                       "+ speed)")


# --------------------------------------------------------------------------- networks (section 4.1)


class QNetwork(nn.Module):
    """Q(s, a): two hidden layers of 64 ReLU units on [s, a]."""

    def __init__(self, obs_dim: int, hidden: int = 64):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.net = mlp([obs_dim + ACT_DIM, hidden, hidden, 1])

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([self.obs_norm(obs), action], 1)).squeeze(1)


class Actor(nn.Module):
    """μ(s): two hidden layers of 64 ReLU units and a tanh output (as DDPG2's actor)."""

    def __init__(self, obs_dim: int, hidden: int = 64):
        super().__init__()
        self.obs_dim = obs_dim
        self.obs_norm = ObservationNormalizer(obs_dim)
        self.net = mlp([obs_dim, hidden, hidden, ACT_DIM], output_activation=nn.Tanh)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.net(self.obs_norm(obs))


def make_policy(args: Args) -> nn.Module:
    """The deterministic actor is the policy itself (`league export` loads weights into it)."""
    return Actor(obs_dim_of(args), args.hidden)


def make_learner(args: Args) -> TD3:
    obs_dim = obs_dim_of(args)
    return TD3(Actor(obs_dim, args.hidden), [QNetwork(obs_dim, args.hidden) for _ in range(args.n_critics)], args)


# --------------------------------------------------------------------------- the learner


class TD3(OffPolicyLearner):
    """Networks, optimizers and updates of Fujimoto et al. (2018), Algorithm 1.

    With one critic, ``policy_frequency=1`` and ``policy_noise=0`` this is DDPG
    (Lillicrap et al. 2016, Algorithm 1).
    """

    def __init__(self, actor: nn.Module, critics: list[nn.Module], args):
        self.args = args
        self.actor = actor
        self.actor_target = copy.deepcopy(actor)
        self.critics = nn.ModuleList(critics)  # qf1, qf2, ...
        self.critics_target = copy.deepcopy(self.critics)
        self.actor_params, self.actor_target_params = list(actor.parameters()), list(self.actor_target.parameters())
        self.q_params, self.q_target_params = list(self.critics.parameters()), list(self.critics_target.parameters())
        self.q_optimizer = adam(self.q_params, lr=args.learning_rate)
        self.actor_optimizer = adam(self.actor_params, lr=args.learning_rate)
        self.optimizers = [self.q_optimizer, self.actor_optimizer]

    def update_critics(self, data) -> dict:
        """y = r + γ (1 − d) min_i Q_targ,i(s', clip(μ_targ(s') + clip(ε, −c, c), −1, 1)), ε ~ N(0, σ̃);
        J_Q = Σ_i E[(Q_i(s, a) − y)²]."""
        args = self.args
        with torch.no_grad():
            noise = torch.randn_like(data.actions) * args.policy_noise
            clipped_noise = noise.clamp(-args.noise_clip, args.noise_clip)
            next_state_actions = (self.actor_target(data.next_observations) + clipped_noise).clamp(-1, 1)
            qf_next_target = torch.stack([qf(data.next_observations, next_state_actions)
                                          for qf in self.critics_target]).min(0).values
            next_q_value = data.rewards + (1 - data.dones) * args.gamma * qf_next_target
        qf_a_values = [qf(data.observations, data.actions) for qf in self.critics]
        qf_losses = [F.mse_loss(q, next_q_value) for q in qf_a_values]
        qf_loss = sum(qf_losses)
        self.q_optimizer.zero_grad()
        qf_loss.backward()
        self.q_optimizer.step()
        losses = {f"qf{i + 1}_loss": loss.detach() for i, loss in enumerate(qf_losses)}
        return losses | {"qf1_values": qf_a_values[0].detach().mean()}

    def update_actor(self, data) -> dict:
        """Deterministic policy gradient: J_μ = −E[Q_1(s, μ(s))]; then the Polyak updates."""
        actor_loss = -self.critics[0](data.observations, self.actor(data.observations)).mean()
        self.actor_optimizer.zero_grad()
        actor_loss.backward()
        self.actor_optimizer.step()
        polyak_update(self.actor_params, self.actor_target_params, self.args.tau)
        polyak_update(self.q_params, self.q_target_params, self.args.tau)
        return {"actor_loss": actor_loss.detach()}

    def fit_normalizers(self, observations: np.ndarray) -> None:
        fit_normalizers([self.actor, self.actor_target, *self.critics, *self.critics_target], observations)

    def act(self, obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Exploration: μ(s) + N(0, σ), clipped to the action bounds."""
        with torch.no_grad():
            actions = self.actor(torch.from_numpy(obs)).numpy()
        noise = rng.normal(0.0, self.args.exploration_noise, actions.shape)
        return np.clip(actions + noise, -1, 1).astype(np.float32)

    def state_dict(self) -> dict:
        return {name: getattr(self, name).state_dict() for name in NETWORKS}

    def load_state_dict(self, state: dict) -> None:
        for name in NETWORKS:
            getattr(self, name).load_state_dict(state[name])


NETWORKS = ("actor", "actor_target", "critics", "critics_target", "q_optimizer", "actor_optimizer")


# --------------------------------------------------------------------------- training


def train(args: Args, run: Run, make: callable = make_learner) -> dict:
    """The shared off-policy loop (league.baselines.common.off_policy) with a TD3 learner, or with
    the learner `make` builds (DDPG's, DDPG with parameter noise's)."""
    return off_policy.train(args, run, make)

"""DDPG with parameter-space noise (the thesis' DDPG2) for MicroRacer.

Plappert et al., "Parameter Space Noise for Exploration", 2018
(https://arxiv.org/abs/1706.01905): instead of adding noise to the actions, explore with a
copy of the actor whose weights are perturbed, θ̃ = θ + N(0, σ²), resampled at each episode.
σ adapts so that the perturbed actions stay at a distance δ from the actor's (section 3,
"adaptive noise scaling"), as OpenAI Baselines' ``adaptive-param_0.2``: σ₀ = δ = 0.2.
The learning is DDPG's, that is TD3's with its tricks switched off (`ddpg.py`): `Args`
subclasses `ddpg.Args` (no action noise), `ParamNoiseDDPG` subclasses `td3.TD3` and overrides
only acting, the actor update (which adapts σ), the end of an episode, the observation
statistics' fit and the checkpoint state (for its perturbed copies), and the training loop is
the shared off-policy one (`common/off_policy.py`).
Thesis: section 4.1 (DDPG2: the actor of TD3, the critic of DDPG), table 4.1 (std 0.2).

    league train ddpg_param_noise --steps 50000 --seed 1 --out runs/ddpg2-1
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
import torch

from league.baselines import ddpg, td3
from league.baselines.common.args import LR_FINAL_HELP, obs_dim_of, option
from league.baselines.common.networks import fit_normalizers
from league.baselines.common.run import Run


@dataclass
class Args(ddpg.Args):
    hidden: int = option(64, "units of the actor's two hidden layers (section 4.1: as TD3's actor)")
    lr_final_fraction: float = option(1.0, LR_FINAL_HELP + "; DDPG2 keeps the constant rate: decayed to 0, its last "
                                           "actors did worse (docs/BASELINES.md)")
    exploration_noise: float = option(0.0, "no action noise: the perturbed weights explore")
    param_noise_std: float = option(0.2, "initial standard deviation σ of the noise on the actor's weights (table 4.1)")
    desired_action_std: float = option(0.2, "target distance δ between perturbed and unperturbed actions (adaptive σ)")
    adaptation_coefficient: float = option(1.01, "σ ← σ·α when the distance is below δ, σ/α above (Plappert et al., "
                                                 "section 3)")
    adapt_every: int = option(50, "adapt σ every this many actor updates")


class ParamNoiseDDPG(td3.TD3):
    """DDPG whose exploration policy is the actor with perturbed weights."""

    def __init__(self, actor, critics, args: Args):
        super().__init__(actor, critics, args)
        self.perturbed_actor = copy.deepcopy(actor)
        self.adaptive_actor = copy.deepcopy(actor)  # a fresh perturbation, to measure the distance
        self.param_noise_std = args.param_noise_std
        self.actor_updates = 0
        self.perturb(self.perturbed_actor)

    @torch.no_grad()
    def perturb(self, target: torch.nn.Module) -> None:
        """θ̃ = θ + N(0, σ²) on every weight and bias of the actor."""
        for param, perturbed in zip(self.actor.parameters(), target.parameters()):
            perturbed.copy_(param + torch.randn_like(param) * self.param_noise_std)

    @torch.no_grad()
    def adapt(self, observations: torch.Tensor) -> float:
        """d = sqrt(E[(μ(s) − μ̃(s))²]) on a batch; σ grows while d < δ and shrinks above it."""
        self.perturb(self.adaptive_actor)
        distance = math.sqrt(torch.mean((self.actor(observations) - self.adaptive_actor(observations)) ** 2).item())
        if distance > self.args.desired_action_std:
            self.param_noise_std /= self.args.adaptation_coefficient
        else:
            self.param_noise_std *= self.args.adaptation_coefficient
        return distance

    def update_actor(self, data) -> dict:
        losses = super().update_actor(data)
        self.actor_updates += 1
        if self.actor_updates % self.args.adapt_every == 0:
            self.adapt(data.observations)
        return losses | {"param_noise_std": self.param_noise_std}

    def fit_normalizers(self, observations: np.ndarray) -> None:
        super().fit_normalizers(observations)
        fit_normalizers([self.perturbed_actor, self.adaptive_actor], observations)  # buffers are not perturbed

    def act(self, obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        with torch.no_grad():
            actions = self.perturbed_actor(torch.from_numpy(obs)).numpy()
        if self.args.exploration_noise > 0:
            actions = actions + rng.normal(0.0, self.args.exploration_noise, actions.shape)
        return np.clip(actions, -1, 1).astype(np.float32)

    def episode_ended(self) -> None:
        self.perturb(self.perturbed_actor)  # a new perturbation for the new episode

    def state_dict(self) -> dict:
        return super().state_dict() | {"perturbed_actor": self.perturbed_actor.state_dict(),
                                       "param_noise_std": self.param_noise_std, "actor_updates": self.actor_updates}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.perturbed_actor.load_state_dict(state["perturbed_actor"])
        self.param_noise_std = float(state["param_noise_std"])
        self.actor_updates = int(state["actor_updates"])


def make_policy(args: Args) -> td3.Actor:
    return td3.Actor(obs_dim_of(args), args.hidden)


def make_learner(args: Args) -> ParamNoiseDDPG:
    obs_dim = obs_dim_of(args)
    return ParamNoiseDDPG(td3.Actor(obs_dim, args.hidden), [ddpg.QNetwork(obs_dim)], args)


def train(args: Args, run: Run) -> dict:
    return td3.train(args, run, make=make_learner)

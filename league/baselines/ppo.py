"""Proximal Policy Optimization (PPO-Clip) for MicroRacer.

Schulman et al., "Proximal Policy Optimization Algorithms", 2017
(https://arxiv.org/abs/1707.06347), with generalized advantage estimation (Schulman et al.,
"High-Dimensional Continuous Control Using Generalized Advantage Estimation", 2016,
https://arxiv.org/abs/1506.02438) and early stopping on a target KL divergence (SpinningUp).
Written after CleanRL's ``ppo_continuous_action.py``.
Thesis: section 1.7.2 (algorithm), section 4.1 (networks), table 4.1 (hyperparameters).
The thesis trained PPO for 600 episodes, "a number of episodes that would give a similar
training time" to the others' 50 000 iterations; here `--steps` counts transitions.

    league train ppo --seed 1 --out runs/ppo-1
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.distributions.normal import Normal

from league.baselines.common.args import CommonArgs, obs_dim_of, option
from league.baselines.common.cars import make_cars
from league.baselines.common.networks import ObservationNormalizer, adam
from league.baselines.common.run import Run
from league.baselines.common.seeding import seed_everything

ACT_DIM = 2  # [acceleration, turn]


@dataclass
class Args(CommonArgs):
    steps: int = option(1_000_000, "environment transitions (about the wall time of 50 000 off-policy iterations)")
    envs: int = option(8, "cars collecting at once, each on its own tracks")
    num_steps: int = option(256, "steps per car in each rollout (rollout = envs × num_steps transitions)")
    learning_rate: float = option(3e-4, "actor and critic learning rate (table 4.1)")
    gamma: float = option(0.99, "discount factor (table 4.1)")
    gae_lambda: float = option(0.95, "λ of generalized advantage estimation (table 4.1)")
    minibatch_size: int = option(64, "mini-batch size (table 4.1)")
    update_epochs: int = option(10, "epochs over each rollout (table 4.1)")
    clip_coef: float = option(0.25, "policy clip ε (table 4.1)")
    ent_coef: float = option(0.01, "entropy bonus coefficient (table 4.1)")
    vf_coef: float = option(0.5, "value loss coefficient")
    max_grad_norm: float = option(0.5, "gradient clipping norm")
    target_kl: float = option(0.01, "stop the epochs of a rollout once the approximate KL exceeds this (table 4.1)")
    norm_adv: bool = option(True, "normalise the advantages in each mini-batch")
    normalize_obs: bool = option(True, "standardise observations with statistics of the first rollout (frozen, "
                                       "exported with the actor)")
    anneal_lr: bool = option(False, "decay the learning rate linearly to 0")
    hidden: int = option(64, "units of the two tanh hidden layers of the actor and the critic (section 4.1)")
    observation: str = option("lidar", "what the agent sees: 'compact' (5 numbers, as the thesis) or 'lidar' (19 rays "
                                       "+ speed)")
    eval_every: int = option(100_000, "evaluate the deterministic actor every this many steps (0: never)")
    checkpoint_every: int = option(100_000, "save a resumable checkpoint every this many steps (0: only at the end)")
    log_every: int = option(1, "write losses every this many rollouts")


# --------------------------------------------------------------------------- networks (section 4.1)


def layer_init(layer: nn.Linear, std: float = math.sqrt(2), bias_const: float = 0.0) -> nn.Linear:
    """Orthogonal initialisation (Engstrom et al. 2020, "Implementation Matters")."""
    torch.nn.init.orthogonal_(layer.weight, std)
    torch.nn.init.constant_(layer.bias, bias_const)
    return layer


class Agent(nn.Module):
    """Critic V(s) and actor N(μ(s), σ²): two hidden layers of 64 tanh units each; the actor's
    mean goes through a tanh (section 4.1); log σ is a free parameter per action."""

    def __init__(self, obs_dim: int, hidden: int = 64):
        super().__init__()
        self.obs_norm = ObservationNormalizer(obs_dim)  # shared by the actor and the critic
        self.critic = nn.Sequential(
            layer_init(nn.Linear(obs_dim, hidden)), nn.Tanh(),
            layer_init(nn.Linear(hidden, hidden)), nn.Tanh(),
            layer_init(nn.Linear(hidden, 1), std=1.0),
        )
        self.actor_mean = nn.Sequential(
            layer_init(nn.Linear(obs_dim, hidden)), nn.Tanh(),
            layer_init(nn.Linear(hidden, hidden)), nn.Tanh(),
            layer_init(nn.Linear(hidden, ACT_DIM), std=0.01), nn.Tanh(),
        )
        self.actor_logstd = nn.Parameter(torch.zeros(1, ACT_DIM))

    def get_value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(self.obs_norm(obs)).squeeze(-1)

    def get_action_and_value(self, obs: torch.Tensor, action: torch.Tensor | None = None):
        action_mean = self.actor_mean(self.obs_norm(obs))
        probs = Normal(action_mean, self.actor_logstd.expand_as(action_mean).exp())
        if action is None:
            action = probs.sample()
        return action, probs.log_prob(action).sum(1), probs.entropy().sum(1), self.get_value(obs)


class DeterministicActor(nn.Module):
    """What is exported and evaluated: the mean action μ(s)."""

    def __init__(self, agent: Agent, obs_dim: int):
        super().__init__()
        self.obs_norm = agent.obs_norm
        self.actor_mean = agent.actor_mean
        self.obs_dim = obs_dim

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.actor_mean(self.obs_norm(obs))


def make_policy(args: Args) -> DeterministicActor:
    obs_dim = obs_dim_of(args)
    return DeterministicActor(Agent(obs_dim, args.hidden), obs_dim)


# --------------------------------------------------------------------------- advantages


def compute_gae(rewards: torch.Tensor, values: torch.Tensor, dones: torch.Tensor, next_value: torch.Tensor,
                gamma: float, gae_lambda: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Generalized advantage estimation (Schulman et al. 2016, eq. 16), backwards in time:

        δ_t = r_t + γ (1 − d_t) V(s_{t+1}) − V(s_t)
        Â_t = δ_t + γ λ (1 − d_t) Â_{t+1}

    Shapes (T, K); ``dones[t]`` is 1 when the episode ended with step t (the next row then
    belongs to a new episode); ``next_value`` (K,) is V of the state after the last row.
    Returns the advantages and the returns Â + V (the critic's targets).
    """
    advantages = torch.zeros_like(rewards)
    lastgaelam = torch.zeros_like(next_value)
    for t in reversed(range(rewards.shape[0])):
        nextvalues = next_value if t == rewards.shape[0] - 1 else values[t + 1]
        nextnonterminal = 1.0 - dones[t]
        delta = rewards[t] + gamma * nextvalues * nextnonterminal - values[t]
        advantages[t] = lastgaelam = delta + gamma * gae_lambda * nextnonterminal * lastgaelam
    return advantages, advantages + values


# --------------------------------------------------------------------------- the update


def ppo_update(agent: Agent, optimizer: torch.optim.Optimizer, b: dict, args: Args,
               rng: np.random.Generator) -> dict:
    """Epochs of mini-batch updates of the clipped objective (Schulman et al. 2017, eq. 7 and 9),
    stopped early when the approximate KL to the rollout's policy exceeds `target_kl`."""
    batch_size = len(b["obs"])
    clipfracs, approx_kl = [], torch.zeros(())
    for epoch in range(args.update_epochs):  # noqa: B007 - read after the loop ("epochs")
        order = rng.permutation(batch_size)
        for start in range(0, batch_size, args.minibatch_size):
            mb = order[start:start + args.minibatch_size]
            _, newlogprob, entropy, newvalue = agent.get_action_and_value(b["obs"][mb], b["actions"][mb])
            logratio = newlogprob - b["logprobs"][mb]
            ratio = logratio.exp()
            with torch.no_grad():
                approx_kl = ((ratio - 1) - logratio).mean()  # k3 estimator (Schulman, "Approximating KL")
                clipfracs.append(((ratio - 1.0).abs() > args.clip_coef).float().mean().item())
            mb_advantages = b["advantages"][mb]
            if args.norm_adv:
                mb_advantages = (mb_advantages - mb_advantages.mean()) / (mb_advantages.std() + 1e-8)
            # L^CLIP = E[min(ρ Â, clip(ρ, 1 − ε, 1 + ε) Â)], as a loss to minimise
            pg_loss1 = -mb_advantages * ratio
            pg_loss2 = -mb_advantages * torch.clamp(ratio, 1 - args.clip_coef, 1 + args.clip_coef)
            pg_loss = torch.max(pg_loss1, pg_loss2).mean()
            v_loss = 0.5 * ((newvalue - b["returns"][mb]) ** 2).mean()
            entropy_loss = entropy.mean()
            loss = pg_loss - args.ent_coef * entropy_loss + v_loss * args.vf_coef
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
            optimizer.step()
        if args.target_kl and approx_kl > args.target_kl:
            break
    return {"policy_loss": pg_loss.item(), "value_loss": v_loss.item(), "entropy": entropy_loss.item(),
            "approx_kl": approx_kl.item(), "clipfrac": float(np.mean(clipfracs)), "epochs": epoch + 1,
            "std": agent.actor_logstd.exp().mean().item()}


# --------------------------------------------------------------------------- training loop


def collect(agent: Agent, cars, obs: np.ndarray, args: Args) -> tuple[dict, np.ndarray]:
    """One rollout of `num_steps` steps of every car. A lap finished or out of time is no
    failure: its last reward gets γ V(s_final) (bootstrapping through the cut, as SB3 does
    for time limits); only a crash ends the return with nothing after it."""
    T, K, d = args.num_steps, args.envs, obs.shape[1]
    r = {"obs": torch.zeros(T, K, d), "actions": torch.zeros(T, K, ACT_DIM), "logprobs": torch.zeros(T, K),
         "rewards": torch.zeros(T, K), "dones": torch.zeros(T, K), "values": torch.zeros(T, K)}
    for t in range(T):
        obs_t = torch.from_numpy(obs)
        with torch.no_grad():
            action, logprob, _, value = agent.get_action_and_value(obs_t)
        step = cars.step(np.clip(action.numpy(), -1, 1))
        rewards = torch.from_numpy(step.rewards)
        cut = step.finished | (step.truncated & ~step.terminated)
        if cut.any():
            with torch.no_grad():
                final_values = agent.get_value(torch.from_numpy(step.next_obs[cut]))
            rewards[torch.from_numpy(cut)] += args.gamma * final_values
        r["obs"][t], r["actions"][t], r["logprobs"][t], r["values"][t] = obs_t, action, logprob, value
        r["rewards"][t], r["dones"][t] = rewards, torch.from_numpy(step.terminated | step.truncated).float()
        obs = cars.obs.copy()
    return r, obs


def train(args: Args, run: Run) -> dict:
    seed_everything(args.seed)
    obs_dim = obs_dim_of(args)
    agent = Agent(obs_dim, args.hidden)
    optimizer = adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    rng = np.random.default_rng(args.seed)  # mini-batch order
    policy = DeterministicActor(agent, obs_dim)
    global_step, rollout_size = 0, args.envs * args.num_steps
    if run.resume:
        global_step, state = run.load_checkpoint()
        agent.load_state_dict(state["agent"])
        optimizer.load_state_dict(state["optimizer"])
        rng.bit_generator.state = state["rng"]
    cars = make_cars(args, seed_offset=global_step)
    obs = cars.reset()
    run.open_progress(args.steps, global_step)

    def state() -> dict:
        return {"agent": agent.state_dict(), "optimizer": optimizer.state_dict(), "rng": rng.bit_generator.state}

    rollouts = 0
    while global_step < args.steps:
        if args.anneal_lr:
            optimizer.param_groups[0]["lr"] = args.learning_rate * max(1.0 - global_step / args.steps, 0.0)
        r, obs = collect(agent, cars, obs, args)
        global_step += rollout_size
        if args.normalize_obs and global_step == rollout_size:
            # the first rollout is the warm-up: it fits the observation statistics, then is dropped
            # (its log-probabilities were computed without them)
            agent.obs_norm.fit(r["obs"].reshape(-1, obs_dim))
            run.record(global_step, cars.pop_episodes())
            continue
        with torch.no_grad():
            next_value = agent.get_value(torch.from_numpy(obs))
        advantages, returns = compute_gae(r["rewards"], r["values"], r["dones"], next_value, args.gamma,
                                          args.gae_lambda)
        batch = {"obs": r["obs"].reshape(-1, obs_dim), "actions": r["actions"].reshape(-1, ACT_DIM),
                 "logprobs": r["logprobs"].reshape(-1), "advantages": advantages.reshape(-1),
                 "returns": returns.reshape(-1)}
        losses = ppo_update(agent, optimizer, batch, args, rng)
        rollouts += 1
        run.record(global_step, cars.pop_episodes())
        if rollouts % args.log_every == 0:
            run.log_losses(global_step, **losses)
        if run.evaluation_due(global_step):
            run.evaluate(global_step, policy)
        if run.checkpoint_due(global_step):
            run.save_checkpoint(global_step, state())
    return run.finish(global_step, policy, state())

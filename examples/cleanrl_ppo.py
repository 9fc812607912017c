"""A CleanRL-style PPO in one file, on the native vector env (`league.vector_env`): N cars, each on
its own tracks, stepped by one call of the compiled core; then the league's own evaluation.

    pip install "torch==2.13.0" "microracer-league[rl]"
    python examples/cleanrl_ppo.py --timesteps 500000 --save ppo_actor.onnx

Paper: Schulman et al., "Proximal Policy Optimization Algorithms", 2017. The loop follows CleanRL's
ppo_continuous_action.py (GAE, clipped surrogate, value loss, minibatch epochs), reduced to what
this env needs: next-step autoreset as Gymnasium 1.x defines it, so the step after a car's episode
ends is its reset and is left out of the update.
"""
from __future__ import annotations

import argparse

import numpy as np
import torch
from torch import nn

import league
from league.agents import export_onnx, load_agent
from league.evaluation import metrics_run


class Agent(nn.Module):
    def __init__(self, obs_dim: int):
        super().__init__()
        self.critic = nn.Sequential(nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(), nn.Linear(64, 1))
        self.actor = nn.Sequential(nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(), nn.Linear(64, 2),
                                   nn.Tanh())
        self.log_std = nn.Parameter(torch.full((2,), -0.5))

    def policy(self, obs: torch.Tensor) -> torch.distributions.Normal:
        return torch.distributions.Normal(self.actor(obs), self.log_std.exp())


def main(argv: list[str] | None = None) -> dict:
    """Train, export, evaluate; returns the steps trained (all cars), the updates, the last rollout's
    mean reward, the evaluation and the actor's path."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=500_000, help="environment steps of training (all cars)")
    parser.add_argument("--envs", type=int, default=16, help="cars of the vector env")
    parser.add_argument("--rollout", type=int, default=128, help="steps per car between updates")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes after training")
    parser.add_argument("--save", default="cleanrl_ppo.onnx", help="the trained actor, as ONNX")
    args = parser.parse_args(argv)
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)  # small MLPs: one thread is fastest

    envs = league.make_vector_env(num_envs=args.envs, max_episode_steps=1000)
    agent = Agent(envs.single_observation_space.shape[0])
    optimizer = torch.optim.Adam(agent.parameters(), lr=3e-4, eps=1e-5)
    obs = torch.as_tensor(envs.reset(seed=args.seed)[0])
    starts = torch.zeros(args.envs, dtype=torch.bool)  # this step only resets the car (next-step autoreset)
    updates = max(1, args.timesteps // (args.envs * args.rollout))
    for _ in range(updates):
        batch = collect(envs, agent, obs, starts, args.rollout)
        rollout_reward = batch["rewards"][batch["valid"]].mean().item()
        obs, starts = batch.pop("next_obs"), batch.pop("next_starts")
        update(agent, optimizer, batch)

    path = export_onnx(agent.actor, args.save)
    result = metrics_run(load_agent(path, name="cleanrl-ppo"), episodes=args.episodes, seed=0)
    print(f"cleanrl-ppo: {args.episodes} episodes, {result.completed} laps, mean return {result.mean_return:.2f}; "
          f"actor saved to {path}")
    return {"timesteps": updates * args.envs * args.rollout, "updates": updates, "rollout_reward": rollout_reward,
            "evaluation": result, "actor": path}


def collect(envs, agent: Agent, obs: torch.Tensor, starts: torch.Tensor, steps: int) -> dict:
    columns = {name: [] for name in ("obs", "actions", "log_probs", "values", "rewards", "dones", "valid")}
    for _ in range(steps):
        with torch.no_grad():
            dist, value = agent.policy(obs), agent.critic(obs).squeeze(-1)
            action = dist.sample()
        next_obs, reward, terminated, truncated, _ = envs.step(action.clamp(-1, 1).numpy())
        for name, item in zip(columns, (obs, action, dist.log_prob(action).sum(-1), value,
                                        torch.as_tensor(reward, dtype=torch.float32),
                                        torch.as_tensor(terminated | truncated), ~starts)):
            columns[name].append(item)
        obs, starts = torch.as_tensor(next_obs), torch.as_tensor(terminated | truncated)
    batch = {name: torch.stack(items) for name, items in columns.items()}
    with torch.no_grad():
        batch["advantages"] = advantages(batch, agent.critic(obs).squeeze(-1))
    return batch | {"next_obs": obs, "next_starts": starts}


def advantages(batch: dict, last_value: torch.Tensor, gamma: float = 0.99, lam: float = 0.95) -> torch.Tensor:
    """GAE; a done step bootstraps nothing, and a reset step (not valid) carries nothing across."""
    result, running, next_value = torch.zeros_like(batch["rewards"]), torch.zeros_like(last_value), last_value
    for t in reversed(range(len(result))):
        keep = (~batch["dones"][t]).float()
        delta = batch["rewards"][t] + gamma * next_value * keep - batch["values"][t]
        running = (delta + gamma * lam * keep * running) * batch["valid"][t].float()
        result[t], next_value = running, batch["values"][t]
    return result


def update(agent: Agent, optimizer, batch: dict, epochs: int = 4, minibatches: int = 4, clip: float = 0.2) -> None:
    valid = batch["valid"].flatten()
    flat = {name: value.flatten(0, 1)[valid] for name, value in batch.items() if name != "valid"}
    returns = flat["advantages"] + flat["values"]
    for _ in range(epochs):
        for index in np.array_split(np.random.permutation(len(returns)), minibatches):
            dist = agent.policy(flat["obs"][index])
            ratio = (dist.log_prob(flat["actions"][index]).sum(-1) - flat["log_probs"][index]).exp()
            advantage = flat["advantages"][index]
            advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
            policy_loss = -torch.min(ratio * advantage, ratio.clamp(1 - clip, 1 + clip) * advantage).mean()
            value_loss = 0.5 * (agent.critic(flat["obs"][index]).squeeze(-1) - returns[index]).pow(2).mean()
            optimizer.zero_grad()
            (policy_loss + 0.5 * value_loss - 0.001 * dist.entropy().sum(-1).mean()).backward()
            nn.utils.clip_grad_norm_(agent.parameters(), 0.5)
            optimizer.step()


if __name__ == "__main__":
    main()

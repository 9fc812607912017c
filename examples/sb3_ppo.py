"""Stable-Baselines3 PPO on the single-car env, then the league's own evaluation of the result.

    pip install "torch==2.13.0" "microracer-league[rl]"
    python examples/sb3_ppo.py --timesteps 200000 --save ppo_microracer.zip

Paper: Schulman et al., "Proximal Policy Optimization Algorithms", 2017. The hyper-parameters
are SB3's defaults; --timesteps 2048 makes a smoke run.
"""
from __future__ import annotations

import argparse

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

import league  # noqa: F401  (registers "league/MicroRacer-v0")
from league.agents import callable_agent
from league.evaluation import metrics_run


def main(argv: list[str] | None = None) -> dict:
    """Train, save, evaluate; returns the steps trained and the evaluation (what it prints)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=200_000, help="environment steps of training")
    parser.add_argument("--envs", type=int, default=4, help="envs stepped together (SB3's DummyVecEnv)")
    parser.add_argument("--seed", type=int, default=1, help="seeds the envs, the network and the sampling")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes after training")
    parser.add_argument("--save", help="write the trained model here (SB3's .zip)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)  # small MLPs: one thread is fastest

    # gym.make through the registry: Gymnasium's TimeLimit keeps the 4000-step limit.
    env = make_vec_env("league/MicroRacer-v0", n_envs=args.envs, seed=args.seed)
    # Steps per env between updates: SB3's default 2048, fewer for a short run.
    model = PPO("MlpPolicy", env, n_steps=max(64, min(2048, args.timesteps // args.envs)), batch_size=64,
                seed=args.seed, verbose=0)
    model.learn(total_timesteps=args.timesteps)
    if args.save:
        model.save(args.save)

    # Any callable from a batch of observations to a batch of actions is a league agent.
    agent = callable_agent(lambda obs: model.predict(obs, deterministic=True)[0], name="sb3-ppo")
    result = metrics_run(agent, episodes=args.episodes, seed=0)
    print(result.table())
    return {"timesteps": model.num_timesteps, "evaluation": result}


if __name__ == "__main__":
    main()

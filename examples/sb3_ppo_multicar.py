"""Stable-Baselines3 PPO on the multi-car PettingZoo env through SuperSuit (parameter sharing).

    pip install "torch==2.13.0" "microracer-league[rl]"
    python examples/sb3_ppo_multicar.py --timesteps 200000

Every car of every race is one of SB3's vector-env slots, and one policy drives them all.
SuperSuit's vector env needs a fixed set of agents, while a car that is done leaves the race:
`black_death_v3` keeps it in the race with zero observations and rewards until every car is
done. SuperSuit's SB3 wrapper does not pass SB3's `seed` on, so the env is seeded once by hand.
"""
from __future__ import annotations

import argparse

import supersuit as ss
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.utils import set_random_seed

import league
from league.agents import callable_agent
from league.evaluation import race


def make_env(n_cars: int, races: int, seed: int):
    env = ss.black_death_v3(league.make_parallel_env(n_cars=n_cars))
    env = ss.pettingzoo_env_to_vec_env_v1(env)
    env = ss.concat_vec_envs_v1(env, races, num_cpus=0, base_class="stable_baselines3")
    env.venv.reset(seed=seed)  # later resets continue from this seed
    return env


def main(argv: list[str] | None = None) -> dict:
    """Train, then race the trained policy against the heuristic driver; returns the steps trained
    (car-steps) and the race (what it prints)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=200_000, help="car-steps of training")
    parser.add_argument("--cars", type=int, default=4, help="cars per race")
    parser.add_argument("--races", type=int, default=2, help="races stepped together")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)  # small MLPs: one thread is fastest

    set_random_seed(args.seed)
    env = make_env(args.cars, args.races, args.seed)
    slots = args.cars * args.races
    # Steps per slot between updates: SB3's default 2048, fewer for a short run.
    model = PPO("MlpPolicy", env, n_steps=max(16, min(2048, args.timesteps // slots)), batch_size=64, verbose=0)
    model.learn(total_timesteps=args.timesteps)

    agent = callable_agent(lambda obs: model.predict(obs, deterministic=True)[0], name="sb3-ppo-shared")
    result = race([agent, "heuristic"], seed=0)
    print(result.table())
    return {"timesteps": model.num_timesteps, "race": result}


if __name__ == "__main__":
    main()

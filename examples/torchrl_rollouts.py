"""torchrl: rollouts of single-car envs in worker processes (GymEnv) and of a multi-car race (PettingZooWrapper).

    pip install "torch==2.13.0" "microracer-league[rl]"
    python examples/torchrl_rollouts.py --steps 1000 --envs 3

The policy is SPEC's heuristic driver as a TensorDictModule; put your torch network in its place.
"""
from __future__ import annotations

import argparse

import torch
from tensordict.nn import TensorDictModule
from torchrl.envs.libs.gym import GymEnv
from torchrl.envs.libs.pettingzoo import PettingZooWrapper

import league
from league.agents import heuristic_actions


def heuristic(observation: torch.Tensor) -> torch.Tensor:
    """SPEC's driver on a tensor of compact observations (..., 5) -> actions (..., 2)."""
    flat = observation.reshape(-1, observation.shape[-1]).numpy()
    return torch.as_tensor(heuristic_actions(flat)).reshape(*observation.shape[:-1], 2)


def single_cars(steps: int, seed: int, num_envs: int = 3) -> dict:
    # num_envs: that many envs in worker processes, each a fresh interpreter: the "league:" prefix
    # makes Gymnasium import league there. numeric_infos: torchrl makes a tensor of every info
    # value, so the outcome's name stays out (its code, "outcome_code", is in).
    env = GymEnv("league:league/MicroRacer-v0", num_envs=num_envs, numeric_infos=True)  # 4000-step limit
    env.set_seed(seed)
    policy = TensorDictModule(heuristic, in_keys=["observation"], out_keys=["action"])
    rollout = env.rollout(steps, policy)  # stops when an episode ends
    env.close()
    returns, progress = rollout["next", "reward"].sum(dim=(1, 2)).tolist(), rollout["next", "progress"][:, -1].tolist()
    print(f"GymEnv: {num_envs} cars, {rollout.shape[1]} steps, returns {', '.join(f'{r:.2f}' for r in returns)}, "
          f"progress {progress}")
    return {"cars": num_envs, "steps": rollout.shape[1], "returns": returns, "progress": progress}


def race(steps: int, seed: int, n_cars: int = 3) -> dict:
    # numeric_infos: torchrl makes a tensor of every info value, so the outcome's name stays out
    # (its code, info["outcome_code"], is in). use_mask: cars that are done are masked out;
    # done_on_any=False: the race goes on until every car is done.
    env = PettingZooWrapper(league.make_parallel_env(n_cars=n_cars, numeric_infos=True), use_mask=True,
                            done_on_any=False, return_state=True, seed=seed)
    policy = TensorDictModule(heuristic, in_keys=[("car", "observation")], out_keys=[("car", "action")])
    rollout = env.rollout(steps, policy)
    final = rollout["next", "car", "info"][-1]
    codes = [league.constants.OUTCOMES[int(c)] for c in final["outcome_code"].flatten()]
    print(f"PettingZooWrapper: {rollout.shape[0]} steps, state {tuple(rollout['state'].shape)}, outcomes {codes}")
    return {"steps": rollout.shape[0], "state_shape": tuple(rollout["state"].shape), "outcomes": codes}


def main(argv: list[str] | None = None) -> dict:
    """Both rollouts; returns what each one prints, under "gym_env" and "race"."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="longest rollout")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--envs", type=int, default=3, help="single-car envs, each in a worker process")
    args = parser.parse_args(argv)
    return {"gym_env": single_cars(args.steps, args.seed, args.envs), "race": race(args.steps, args.seed)}


if __name__ == "__main__":
    main()

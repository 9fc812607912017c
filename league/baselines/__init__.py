"""Baselines: DDPG, DDPG with parameter noise, TD3, SAC, DSAC and PPO in PyTorch.

One readable file per algorithm (CleanRL style) plus `common` for what they really share.
`league train ALGO` and `league export RUN` are in `league.baselines.cli`. torch is imported
only when an algorithm is loaded, so listing them stays cheap.
"""
from __future__ import annotations

import importlib
from types import ModuleType

# algorithm name -> module; the thesis' names as aliases
ALGORITHMS = {
    "ddpg": "league.baselines.ddpg",
    "ddpg_param_noise": "league.baselines.ddpg_param_noise",
    "td3": "league.baselines.td3",
    "sac": "league.baselines.sac",
    "dsac": "league.baselines.dsac",
    "ppo": "league.baselines.ppo",
}
ALIASES = {"ddpg2": "ddpg_param_noise", "ddpg-param-noise": "ddpg_param_noise"}


def canonical_name(name: str) -> str:
    """The algorithm's canonical name, or ValueError naming the valid ones."""
    key = name.lower()
    key = ALIASES.get(key, key)
    if key not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {name!r}: choose one of {', '.join(ALGORITHMS)} "
                         "(ddpg2 = ddpg_param_noise)")
    return key


def load_algorithm(name: str) -> ModuleType:
    """The module of an algorithm: its `Args`, `make_policy(args)` and `train(args, run)`."""
    return importlib.import_module(ALGORITHMS[canonical_name(name)])

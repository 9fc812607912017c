"""Baselines: DDPG, DDPG with parameter noise, TD3, SAC, DSAC and PPO in PyTorch.

One readable file per algorithm (CleanRL style) plus `common` for what they really share.
`league train ALGO` and `league export RUN` are in `league.baselines.cli`; `export_run` is here,
beside the registry it needs (`common` never imports this package). torch is imported only when
an algorithm is loaded or a run exported, so listing them stays cheap.
"""
from __future__ import annotations

import importlib
import json
import os
from pathlib import Path
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


def export_run(folder: str | os.PathLike, fmt: str, out: str | os.PathLike, which: str = "best") -> Path:
    """Load a run's actor weights into a fresh deterministic actor and export it (checked)."""
    from league.baselines.common.args import TrainError
    from league.baselines.common.export import export_policy
    from league.baselines.common.run import load_state

    folder = Path(folder)
    config_path, weights = folder / "config.json", folder / f"policy_{which}.pt"
    if not config_path.is_file():
        raise TrainError(f"{folder} is not a training run (no config.json); train one with 'league train ALGO'")
    if not weights.is_file():
        raise TrainError(f"{folder} has no {weights.name} yet: the run has not finished (resume it with --resume)")
    config = json.loads(config_path.read_text())
    module = load_algorithm(config["algorithm"])
    policy = module.make_policy(module.Args(**config["args"]))
    policy.load_state_dict(load_state(weights))
    return export_policy(policy, out, fmt, config["obs_dim"])

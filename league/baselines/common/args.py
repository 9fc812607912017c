"""The arguments every baseline has, their checks, and the error of a request that cannot be honoured.

Each algorithm's `Args` dataclass extends `CommonArgs`; every field is an `option(default, help)`,
and `league train ALGO` makes each one a command-line option with that help.
"""
from __future__ import annotations

import dataclasses
from typing import Any


LR_FINAL_HELP = ("the learning rates decay linearly to this fraction of their initial value at the last step "
                 "(SB3's get_linear_fn; 1: constant, as the thesis)")


class TrainError(ValueError):
    """A training or export request that cannot be honoured; the message is one line for the user."""


def option(default: Any, help: str) -> Any:
    """A field of an `Args` dataclass with its `--help` text (what Python 3.14 writes `field(doc=...)`)."""
    return dataclasses.field(default=default, metadata={"help": help})


@dataclasses.dataclass
class CommonArgs:
    """Arguments every baseline has; each algorithm's `Args` adds its hyperparameters."""

    seed: int = option(1, "seed of the networks, the exploration and the training tracks")
    steps: int = option(50_000, "training iterations: environment transitions collected "
                                "(off-policy: one gradient update each)")
    envs: int = option(1, "cars collecting at once, each on its own tracks (K transitions per iteration)")
    observation: str = option("compact", "what the agent sees: 'compact' (5 numbers, as the thesis) "
                                         "or 'lidar' (19 rays + speed)")
    neutral_prob: float = option(0.1, "probability of the thesis' neutral [0, 0] action after a chosen one "
                                      "(training only)")
    obstacles: bool = option(True, "obstacles on the training tracks")
    chicanes: bool = option(True, "a chicane on the training tracks")
    turn_limit: bool = option(True, "speed-dependent turn limit")
    low_speed_termination: bool = option(True, "end episodes below speed 0.05")
    eval_every: int = option(5_000, "evaluate the deterministic actor every this many steps (0: never)")
    eval_episodes: int = option(50, "episodes of each periodic evaluation (validation tracks, seed eval_seed)")
    eval_seed: int = option(12345, "seed of the periodic evaluations' tracks (the final evaluation uses seed 0)")
    final_eval_episodes: int = option(100, "episodes of the final evaluation on `league evaluate`'s tracks (seed 0); "
                                           "0 to skip")
    checkpoint_every: int = option(10_000, "save a resumable checkpoint every this many steps (0: only at the end)")
    log_every: int = option(500, "write losses every this many steps")
    normalize_obs: bool = option(True, "standardise observations with statistics of the warm-up data "
                                       "(frozen, exported with the actor)")


def check_args(args: CommonArgs) -> None:
    """Raise TrainError, naming the option, for values no run can use."""
    if args.observation not in ("compact", "lidar"):
        raise TrainError(f"--observation must be 'compact' or 'lidar', got {args.observation!r}")
    for name in ("steps", "envs"):
        if getattr(args, name) < 1:
            raise TrainError(f"--{name} must be at least 1, got {getattr(args, name)}")
    if not 0 <= args.neutral_prob <= 1:
        raise TrainError(f"--neutral-prob must be in [0, 1], got {args.neutral_prob}")
    if not 0 <= getattr(args, "lr_final_fraction", 1.0) <= 1:
        raise TrainError(f"--lr-final-fraction must be in [0, 1], got {args.lr_final_fraction}")
    if args.normalize_obs and getattr(args, "learning_starts", 2) < 2:
        raise TrainError("--normalize-obs fits its statistics on the warm-up data: give --learning-starts 2 or more, "
                         "or --no-normalize-obs")


def obs_dim_of(args: CommonArgs) -> int:
    return 5 if args.observation == "compact" else 20


def env_options_of(args: CommonArgs) -> dict:
    """The environment options of a run (evaluations use the same, with the agent's observation)."""
    return {"obstacles": args.obstacles, "chicanes": args.chicanes, "turn_limit": args.turn_limit,
            "low_speed_termination": args.low_speed_termination}

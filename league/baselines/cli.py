"""`league train` and `league export`: train a baseline, export its deterministic actor.

    league train sac --steps 50000 --seed 1 --out runs/sac-1
    league train sac --out runs/sac-1 --resume            # go on after an interruption
    league train sac --help                               # every hyperparameter of SAC
    league export runs/sac-1 --format onnx --out sac.onnx

`league.cli` calls `add_commands(subparsers)`; `python -m league.baselines.cli` runs the two
commands on their own. Errors print one line and exit with status 2.
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import json
import os
import sys
import textwrap
from pathlib import Path
from typing import Any, Sequence

from league.baselines import ALGORITHMS, canonical_name, load_algorithm

EXIT_ERROR = 2
RUN_OPTIONS = ("out", "resume", "no_progress")  # options of the command, not of the algorithm


def add_commands(subparsers) -> None:
    """Add `train` and `export` to the `league` command's subparsers."""
    train = subparsers.add_parser(
        "train", help="train a baseline (ddpg, ddpg_param_noise, td3, sac, dsac, ppo)",
        description="Train a baseline with the thesis' networks and hyperparameters; log metrics (CSV, and "
                    "TensorBoard if installed), evaluate periodically, checkpoint, draw the training curves. "
                    "'league train ALGO --help' lists the algorithm's options.",
        epilog="example: league train sac --steps 50000 --seed 1 --out runs/sac-1")
    train.add_argument("algorithm", metavar="ALGO", help=f"one of {', '.join(ALGORITHMS)} (ddpg2 = ddpg_param_noise)")
    train.add_argument("options", nargs=argparse.REMAINDER, metavar="...",
                       help="--steps N --seed S --out FOLDER --envs K --resume, and the algorithm's options")
    train.set_defaults(run=run_train)

    export = subparsers.add_parser(
        "export", help="export a trained baseline's deterministic actor to ONNX or TorchScript",
        description="Write the deterministic actor (the mean action, no noise) of a training run as an ONNX or "
                    "TorchScript file for 'league evaluate', races and the league server. The file is loaded "
                    "back and its actions checked against the torch actor's.")
    export.add_argument("run_folder", metavar="RUN", help="a run folder written by 'league train'")
    export.add_argument("--format", choices=("onnx", "torchscript"), default="onnx", help="file format (default onnx)")
    export.add_argument("--out", metavar="FILE", required=True, help="the file to write (.onnx or .pt)")
    export.add_argument("--which", choices=("best", "final"), default="best",
                        help="the actor of the best periodic evaluation (default) or the final one")
    export.set_defaults(run=run_export)


# --------------------------------------------------------------------------- train


def algorithm_parser(name: str, args_class: type) -> argparse.ArgumentParser:
    """Options from the fields of the algorithm's `Args` dataclass; help from their docstrings.

    Defaults are SUPPRESSed so that only the options given on the command line override a
    resumed run's saved arguments.
    """
    parser = argparse.ArgumentParser(prog=f"league train {name}", argument_default=argparse.SUPPRESS,
                                     description=f"Train {name}; every option below has the thesis' default.")
    parser.add_argument("--out", metavar="FOLDER", help=f"the run folder (default runs/{name}-seedS)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    docs = field_docs(args_class)
    defaults = args_class()
    for field in dataclasses.fields(args_class):
        flag = "--" + field.name.replace("_", "-")
        default = getattr(defaults, field.name)
        text = f"{docs.get(field.name, '')} (default {default})"
        if field.type in ("bool", bool):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, help=text)
        else:
            kind = {"int": int, "float": float, "str": str}.get(field.type, type(default))
            parser.add_argument(flag, type=kind, metavar=field.name.upper(), help=text)
    return parser


def field_docs(cls: type) -> dict[str, str]:
    """The docstring under each field of a dataclass and of its bases (CleanRL's convention)."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if klass is object or not dataclasses.is_dataclass(klass):
            continue
        tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        body = tree.body[0].body
        for node, after in zip(body, body[1:]):
            if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and isinstance(after, ast.Expr)
                    and isinstance(after.value, ast.Constant) and isinstance(after.value.value, str)):
                docs[node.target.id] = " ".join(after.value.value.split())
    return docs


def run_train(args: argparse.Namespace) -> int:
    from league.baselines.common import Run, TrainError

    name = canonical_name(args.algorithm)
    module = load_algorithm(name)
    options = vars(algorithm_parser(name, module.Args).parse_args(args.options))
    folder = Path(options.get("out") or f"runs/{name}-seed{options.get('seed', module.Args().seed)}")
    resume = options.get("resume", False)
    values = saved_args(folder, name) if resume else {}
    values.update({k: v for k, v in options.items() if k not in RUN_OPTIONS})
    try:
        train_args = module.Args(**values)
    except TypeError as error:
        raise TrainError(f"{folder}/config.json does not match {name}'s arguments: {error}") from error
    check_args(train_args)
    run = Run(folder, name, train_args, resume=resume, progress=not options.get("no_progress", False))
    try:
        summary = module.train(train_args, run)
    finally:
        run.close()
    print(summary_text(folder, summary))
    return 0


def saved_args(folder: Path, name: str) -> dict:
    """The arguments of the run to resume (checked further by `Run`)."""
    from league.baselines.common import TrainError

    config = folder / "config.json"
    if not (folder / "checkpoint.pt").is_file() or not config.is_file():
        raise TrainError(f"no run to resume in {folder}: it has no checkpoint.pt and config.json "
                         f"(start one with 'league train {name} --out {folder}')")
    saved = json.loads(config.read_text())
    if saved.get("algorithm") != name:
        raise TrainError(f"{folder} holds a {saved.get('algorithm')} run, not {name}")
    return dict(saved["args"])


def check_args(args: Any) -> None:
    from league.baselines.common import TrainError

    if args.observation not in ("compact", "lidar"):
        raise TrainError(f"--observation must be 'compact' or 'lidar', got {args.observation!r}")
    for name in ("steps", "envs"):
        if getattr(args, name) < 1:
            raise TrainError(f"--{name} must be at least 1, got {getattr(args, name)}")
    if not 0 <= args.neutral_prob <= 1:
        raise TrainError(f"--neutral-prob must be in [0, 1], got {args.neutral_prob}")
    if args.normalize_obs and getattr(args, "learning_starts", 2) < 2:
        raise TrainError("--normalize-obs fits its statistics on the warm-up data: give --learning-starts 2 or more, "
                         "or --no-normalize-obs")


def summary_text(folder: Path, summary: dict) -> str:
    lines = [f"{summary['algorithm']} seed {summary['seed']}: {summary['steps']} steps in "
             f"{summary['training_seconds'] / 60:.1f} min ({folder})"]
    for which, result in summary.get("final_eval", {}).items():
        lines.append(f"  {which:<5} actor: completed {result['completed']}/{result['episodes']}, mean return "
                     f"{result['mean_return']:.2f}, mean steps {result['mean_steps']:.0f}, mean speed "
                     f"{result['mean_speed']:.3f}")
    lines.append(f"export: league export {folder} --format onnx --out {summary['algorithm']}.onnx")
    return "\n".join(lines)


# --------------------------------------------------------------------------- export


def run_export(args: argparse.Namespace) -> int:
    path = export_run(args.run_folder, args.format, args.out, args.which)
    print(f"{args.which} actor of {args.run_folder} exported to {path}")
    return 0


def export_run(folder: str | os.PathLike, fmt: str, out: str | os.PathLike, which: str = "best") -> Path:
    """Load a run's actor weights into a fresh deterministic actor and export it (checked)."""
    from league.baselines.common import TrainError, export_policy, load_state

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


# --------------------------------------------------------------------------- standalone


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m league.baselines.cli train|export ...`, with the `league` command's error style."""
    parser = argparse.ArgumentParser(prog="league", description="Train and export MicroRacer baselines.")
    add_commands(parser.add_subparsers(dest="command", metavar="COMMAND", required=True))
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except KeyboardInterrupt:
        print("league: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as error:
        if os.environ.get("LEAGUE_DEBUG"):
            raise
        print(f"league: error: {' '.join(str(error).split())}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())

"""`league train` and `league export`: train a baseline, export its deterministic actor.

    league train sac --steps 50000 --seed 1 --out runs/sac-1
    league train sac --out runs/sac-1 --resume            # go on after an interruption
    league train sac --help                               # every hyperparameter of SAC
    league export runs/sac-1 --format onnx --out sac.onnx

`league.cli` calls `add_commands(subparsers)` and prints errors as one line (exit status 2).
Each algorithm's options are the fields of its `Args` dataclass, with the help of their `option`.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import typing
from pathlib import Path

from league.baselines import ALGORITHMS, canonical_name, export_run, load_algorithm
from league.baselines.common.args import TrainError, check_args

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
    """An option per field of the algorithm's `Args` dataclass, its help from the field's `option`.

    Defaults are SUPPRESSed so that only the options given on the command line override a
    resumed run's saved arguments.
    """
    parser = argparse.ArgumentParser(prog=f"league train {name}", argument_default=argparse.SUPPRESS,
                                     description=f"Train {name}; every option below has the thesis' default.")
    parser.add_argument("--out", metavar="FOLDER", help=f"the run folder (default runs/{name}-seedS)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    types = typing.get_type_hints(args_class)  # the annotations are strings (`from __future__ import annotations`)
    for field in dataclasses.fields(args_class):
        flag = "--" + field.name.replace("_", "-")
        text = f"{field.metadata['help']} (default {field.default})"
        if types[field.name] is bool:
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, help=text)
        else:
            parser.add_argument(flag, type=types[field.name], metavar=field.name.upper(), help=text)
    return parser


def run_train(args: argparse.Namespace) -> int:
    from league.baselines.common.run import Run  # torch: only when a command runs

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
    config = folder / "config.json"
    if not (folder / "checkpoint.pt").is_file() or not config.is_file():
        raise TrainError(f"no run to resume in {folder}: it has no checkpoint.pt and config.json "
                         f"(start one with 'league train {name} --out {folder}')")
    saved = json.loads(config.read_text())
    if saved.get("algorithm") != name:
        raise TrainError(f"{folder} holds a {saved.get('algorithm')} run, not {name}")
    return dict(saved["args"])


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

"""The baselines' results table, training curves and bundled agents, from finished runs.

    # 1. train (one process at a time on a shared machine; each prints its own summary)
    for algo in ddpg ddpg_param_noise td3 sac dsac ppo; do for seed in 1 2 3; do
        nice -n 10 league train $algo --seed $seed --out runs/$algo-$seed --no-progress
    done; done
    # 2. evaluate every run's exported actor, print the README table, draw the curves, bundle
    python benchmarks/baselines_report.py runs --curves docs/baselines_curves.png \
        --bundle league/baselines/agents

Every run's deterministic actor (by default the one of its best periodic evaluation on
validation tracks of seed 12345, ranked by racing score = completed fraction × mean speed)
is exported to ONNX and evaluated like `league evaluate
AGENT --episodes 100 --seed 0`, all environment options on. The bundled agent of an
algorithm is its run with the best validation score, chosen without looking at the seed-0
evaluation; its metadata also holds a second evaluation on fresh tracks (seed 2026).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from league.agents import load_agent
from league.baselines import ALGORITHMS, export_run, load_algorithm
from league.baselines.common.evaluation import eval_key
from league.baselines.common.logger import read_csv
from league.baselines.common.plots import moving_average
from league.evaluation import metrics_run

THESIS = {  # tables 4.2 and 4.3: mean training time, mean / best completed, mean return, mean speed
    "ddpg": ("41 min", 38, 90, 2.48, 0.34), "ddpg_param_noise": ("54 min", 18, 39, 0.80, 0.30),
    "td3": ("1 h 10", 54, 80, 3.52, 0.26), "sac": ("1 h 11", 69, 79, 4.61, 0.29),
    "dsac": ("53 min", 37, 75, 2.84, 0.34), "ppo": ("45 min", 37, 62, 2.05, 0.23),
}
LABELS = {"ddpg": "DDPG", "ddpg_param_noise": "DDPG2", "td3": "TD3", "sac": "SAC", "dsac": "DSAC", "ppo": "PPO"}
EVAL_SEED, CHECK_SEED, EPISODES = 0, 2026, 100


def find_runs(root: Path) -> dict[str, list[Path]]:
    runs: dict[str, list[Path]] = {}
    for summary in sorted(root.glob("*/summary.json")):
        algorithm = json.loads(summary.read_text())["algorithm"]
        runs.setdefault(algorithm, []).append(summary.parent)
    return runs


def evaluate_run(folder: Path, which: str, seed: int = EVAL_SEED) -> dict:
    """Export the run's actor to ONNX and evaluate the file, as a student would."""
    with tempfile.TemporaryDirectory() as tmp:
        path = export_run(folder, "onnx", Path(tmp) / "actor.onnx", which)
        result = metrics_run(load_agent(path), episodes=EPISODES, seed=seed)
    return {"completed": result.completed, "episodes": result.episodes_total, "mean_return": result.mean_return,
            "mean_steps": result.mean_steps, "mean_speed": result.mean_speed, "outcomes": result.outcome_counts()}


def run_record(folder: Path, which: str) -> dict:
    summary = json.loads((folder / "summary.json").read_text())
    return {"folder": str(folder), "seed": summary["seed"], "steps": summary["steps"],
            "training_seconds": summary["training_seconds"], "validation": summary["best_periodic_eval"],
            "evaluation": evaluate_run(folder, which)}


def table(records: dict[str, list[dict]], which: str) -> str:
    lines = [
        "| method | seeds | training time (mean) | completed / 100: mean (best) | mean return | mean steps | "
        "mean speed | thesis: time, completed mean (best), return, speed |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for algorithm in ALGORITHMS:
        rows = records.get(algorithm)
        if not rows:
            continue
        ev = [r["evaluation"] for r in rows]
        minutes = np.mean([r["training_seconds"] for r in rows]) / 60
        completed = [e["completed"] for e in ev]
        t = THESIS[algorithm]
        lines.append(
            f"| {LABELS[algorithm]} | {len(rows)} | {minutes:.1f} min | {np.mean(completed):.0f} ({max(completed)}) | "
            f"{np.mean([e['mean_return'] for e in ev]):.2f} | {np.mean([e['mean_steps'] for e in ev]):.0f} | "
            f"{np.mean([e['mean_speed'] for e in ev]):.2f} | {t[0]}, {t[1]} ({t[2]}), {t[3]:.2f}, {t[4]:.2f} |")
    return "\n".join(lines)


def per_seed_table(records: dict[str, list[dict]]) -> str:
    lines = ["| method | seed | steps | training time | completed | mean return | mean steps | mean speed |",
             "|---|---|---|---|---|---|---|---|"]
    for algorithm in ALGORITHMS:
        for r in records.get(algorithm, []):
            e = r["evaluation"]
            lines.append(f"| {LABELS[algorithm]} | {r['seed']} | {r['steps']} | {r['training_seconds'] / 60:.1f} min | "
                         f"{e['completed']} | {e['mean_return']:.2f} | {e['mean_steps']:.0f} | {e['mean_speed']:.3f} |")
    return "\n".join(lines)


def plot(runs: dict[str, list[Path]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    algorithms = [a for a in ALGORITHMS if a in runs]
    rows = -(-len(algorithms) // 3)  # three panels a row
    fig, axes = plt.subplots(rows, 3, figsize=(14, 0.5 + 3.5 * rows), squeeze=False)
    for ax, algorithm in zip(axes.flat, algorithms):
        for i, folder in enumerate(runs[algorithm]):
            charts, evals = read_csv(folder / "charts.csv"), read_csv(folder / "eval.csv")
            seed = json.loads((folder / "summary.json").read_text())["seed"]
            if charts:
                steps = [float(r["global_step"]) for r in charts]
                done = moving_average(np.array([float(r["completed"]) for r in charts]))
                ax.plot(steps, 100 * done, color=f"C{i}", alpha=0.45, linewidth=1)
            if evals:
                ax.plot([float(r["global_step"]) for r in evals],
                        [100 * float(r["completed"]) / float(r["episodes"]) for r in evals], "o-", color=f"C{i}",
                        markersize=3, label=f"seed {seed}")
        ax.set(title=LABELS[algorithm], xlabel="global step", ylabel="completed laps (%)", ylim=(-2, 102))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    for ax in list(axes.flat)[len(algorithms):]:
        ax.axis("off")
    fig.suptitle("MicroRacer baselines: training episodes (lines, moving mean of 20) and periodic evaluations "
                 "(dots, 50 validation tracks)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def bundle(algorithm: str, rows: list[dict], folder: Path, which: str) -> dict:
    """Bundle the run with the best validation score (not the best seed-0 score) as <algorithm>.onnx."""
    chosen = max(rows, key=lambda r: eval_key(r["validation"]))
    run = Path(chosen["folder"])
    export_run(run, "onnx", folder / f"{algorithm}.onnx", which)
    config = json.loads((run / "config.json").read_text())
    metadata = {
        "name": algorithm, "algorithm": LABELS[algorithm], "file": f"{algorithm}.onnx", "seed": chosen["seed"],
        "steps": chosen["steps"], "training_seconds": chosen["training_seconds"], "actor": which,
        "observation": config["args"]["observation"], "obs_dim": config["obs_dim"],
        "chosen_by": "the best racing score (completed fraction x mean speed) of the periodic validation "
                     "evaluations among the trained seeds (50 episodes on tracks of seed 12345)",
        "validation": chosen["validation"],
        "evaluation": {"command": f"league evaluate {algorithm}.onnx --episodes {EPISODES} --seed {EVAL_SEED}",
                       **chosen["evaluation"]},
        "evaluation_fresh_tracks": {"seed": CHECK_SEED, **evaluate_run(run, which, CHECK_SEED)},
        "args": config["args"], "versions": config["versions"],
        "train_command": train_command(algorithm, config["args"]),
    }
    (folder / f"{algorithm}.json").write_text(json.dumps(metadata, indent=2) + "\n")
    return metadata


def train_command(algorithm: str, args: dict) -> str:
    """The `league train` command that reproduces a run: its seed and steps, and every argument
    that differs from today's defaults (so that a later change of a default does not change it)."""
    defaults = dataclasses.asdict(load_algorithm(algorithm).Args())
    words = ["league", "train", algorithm, "--seed", str(args["seed"]), "--steps", str(args["steps"])]
    for name, value in args.items():
        if name not in ("seed", "steps") and value != defaults.get(name):
            flag = "--" + name.replace("_", "-")
            words += [flag if value else f"--no-{flag[2:]}"] if isinstance(value, bool) else [flag, str(value)]
    return " ".join(words)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, help="a folder of run folders (each written by 'league train')")
    parser.add_argument("--which", choices=("best", "final"), default="best", help="which actor of each run")
    parser.add_argument("--curves", type=Path, help="write the training curves to this PNG")
    parser.add_argument("--bundle", type=Path, help="write <algo>.onnx and <algo>.json of each algorithm here")
    parser.add_argument("--json", type=Path, help="write every run's figures to this JSON file")
    args = parser.parse_args(argv)
    runs = find_runs(args.runs)
    if not runs:
        print(f"no finished runs in {args.runs}", file=sys.stderr)
        return 2
    records = {a: [run_record(folder, args.which) for folder in folders] for a, folders in runs.items()}
    print(table(records, args.which))
    print()
    print(per_seed_table(records))
    if args.json:
        args.json.write_text(json.dumps(records, indent=2))
    if args.curves:
        plot(runs, args.curves)
        print(f"\ncurves: {args.curves}", file=sys.stderr)
    if args.bundle:
        args.bundle.mkdir(parents=True, exist_ok=True)
        for algorithm, rows in records.items():
            meta = bundle(algorithm, rows, args.bundle, args.which)
            e = meta["evaluation"]
            print(f"bundled {algorithm}: seed {meta['seed']}, {e['completed']}/100, speed {e['mean_speed']:.3f}",
                  file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

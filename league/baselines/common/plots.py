"""The training curves of a run, drawn from its CSV files."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from league.baselines.common.logger import read_csv

RECENT_EPISODES = 20  # window of the curves' moving averages and of the progress bar's return and completion rate


def plot_curves(folder: str | os.PathLike, save: str | os.PathLike | None = None) -> Path:
    """Training curves of a run: episodic return and completion rate (moving averages over
    episodes) and the periodic evaluations, against the global step."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    folder = Path(folder)
    charts, evals = read_csv(folder / "charts.csv"), read_csv(folder / "eval.csv")
    config = json.loads((folder / "config.json").read_text())
    fig, (ax_return, ax_done) = plt.subplots(1, 2, figsize=(11, 4))
    if charts:
        steps = np.array([float(r["global_step"]) for r in charts])
        returns = np.array([float(r["episodic_return"]) for r in charts])
        done = np.array([float(r["completed"]) for r in charts])
        ax_return.plot(steps, returns, ".", color="0.75", markersize=3, label="episode")
        ax_return.plot(steps, moving_average(returns), color="C0", label=f"mean of {RECENT_EPISODES}")
        ax_done.plot(steps, 100 * moving_average(done), color="C0", label=f"training (last {RECENT_EPISODES})")
    if evals:
        steps = [float(r["global_step"]) for r in evals]
        ax_return.plot(steps, [float(r["mean_return"]) for r in evals], "o-", color="C1", label="evaluation")
        ax_done.plot(steps, [100 * float(r["completed"]) / float(r["episodes"]) for r in evals], "o-", color="C1",
                     label="evaluation")
    ax_return.set(xlabel="global step", ylabel="episodic return", title=f"{config['algorithm']} seed "
                  f"{config['args']['seed']}")
    ax_done.set(xlabel="global step", ylabel="completed laps (%)", ylim=(-2, 102), title="completion")
    for ax in (ax_return, ax_done):
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    path = Path(save) if save else folder / "curves.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def moving_average(values: np.ndarray, window: int = RECENT_EPISODES) -> np.ndarray:
    """Mean of the last `window` values at each point (fewer at the start)."""
    cumsum = np.cumsum(np.insert(np.asarray(values, dtype=float), 0, 0.0))
    idx = np.arange(1, len(values) + 1)
    lo = np.maximum(idx - window, 0)
    return (cumsum[idx] - cumsum[lo]) / (idx - lo)


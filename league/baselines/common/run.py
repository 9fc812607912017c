"""A training run: its folder, progress bar, logs, periodic evaluations, checkpoints and end.

An algorithm's loop calls `Run`; a run folder (``league train ALGO --out runs/NAME``) holds::

    config.json        algorithm, arguments, observation size, versions
    charts.csv         one row per finished training episode (return, steps, outcome, speed)
    losses.csv         losses and coefficients, every ``log_every`` steps
    eval.csv           periodic ``metrics_run`` evaluations of the deterministic actor
    checkpoint.pt      the latest training state, for --resume (torch.save of state dicts)
    policy_final.pt    the actor's weights at the end (state dict)
    policy_best.pt     the actor's weights at its best periodic evaluation
    summary.json       training time and the final 100-episode evaluation
    curves.png         the training curves
"""
from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from collections import deque
from pathlib import Path

import numpy as np
import torch
from torch import nn

from league.baselines.common.args import CommonArgs, TrainError, env_options_of, obs_dim_of
from league.baselines.common.cars import EpisodeStats
from league.baselines.common.evaluation import FINAL_EVAL_SEED, eval_key, evaluate
from league.baselines.common.logger import Logger
from league.baselines.common.plots import RECENT_EPISODES, plot_curves
from league.baselines.common.seeding import global_rng_state, set_global_rng_state


def save_state(state: dict, path: Path) -> None:
    """torch.save of our own state dicts, written atomically (an interrupted save keeps the old file)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def load_state(path: Path) -> dict:
    """Load a file written by `save_state`: tensors and plain data only (weights_only: no pickled code)."""
    return torch.load(path, map_location="cpu", weights_only=True)


class Run:
    """A training run: its folder, logger, progress bar, periodic evaluation and checkpoints.

    The algorithm's loop calls `record(global_step, episodes)` after each iteration,
    `log_losses(...)` now and then, and `checkpoint_due` / `save_checkpoint`; `finish` writes
    the final actor, the summary and the curves.
    """

    def __init__(self, folder: str | os.PathLike, algorithm: str, args: CommonArgs, *, resume: bool = False,
                 progress: bool = True, tensorboard: bool = True):
        self.folder = Path(folder)
        self.algorithm = algorithm
        self.args = args
        self.resume = resume
        self.checkpoint_path = self.folder / "checkpoint.pt"
        prepare_folder(self.folder, resume)
        self.config = self._write_config()
        self.logger = Logger(self.folder, tensorboard=tensorboard)
        self.show_progress = progress
        self.bar = None
        self.recent: deque[EpisodeStats] = deque(maxlen=RECENT_EPISODES)
        self.best_eval: dict | None = None
        self.last_eval: dict | None = None
        self.episodes_done = 0
        self.elapsed_before = 0.0  # seconds of training before a resume
        self.eval_seconds = 0.0
        self.start_time = time.perf_counter()
        self.start_step = 0  # the first step of this process (for SPS)
        self.next_eval = args.eval_every
        self.next_checkpoint = args.checkpoint_every

    # -- config -------------------------------------------------------------------------

    def _write_config(self) -> dict:
        path = self.folder / "config.json"
        config = {"algorithm": self.algorithm, "args": dataclasses.asdict(self.args), "obs_dim": obs_dim_of(self.args),
                  "versions": {"python": sys.version.split()[0], "torch": torch.__version__, "numpy": np.__version__}}
        if self.resume and path.exists():
            old = json.loads(path.read_text())
            if old.get("algorithm") != self.algorithm:
                raise TrainError(f"{self.folder} holds a {old.get('algorithm')} run, not {self.algorithm}")
            config["resumed_from"] = old
        path.write_text(json.dumps(config, indent=2))
        return config

    # -- progress -----------------------------------------------------------------------

    def open_progress(self, total: int, initial: int) -> None:
        from tqdm.auto import tqdm

        self.start_step, self.start_time = initial, time.perf_counter()
        self.bar = tqdm(total=total, initial=initial, desc=self.algorithm, unit="step", dynamic_ncols=True,
                        disable=not self.show_progress, mininterval=0.5, file=sys.stderr)

    def record(self, global_step: int, episodes: list[EpisodeStats]) -> None:
        """Log finished training episodes and move the progress bar to `global_step`."""
        for e in episodes:
            self.episodes_done += 1
            self.recent.append(e)
            self.logger.log("charts", global_step, episodic_return=round(e.episode_return, 5),
                            episodic_length=e.steps, completed=int(e.outcome == "finished"),
                            mean_speed=round(e.mean_speed, 5), outcome=e.outcome)
        if self.bar is not None:
            self.bar.update(global_step - self.bar.n)
            if episodes:
                self.bar.set_postfix(self.postfix(), refresh=False)

    def postfix(self) -> dict:
        recent = list(self.recent)
        values = {"ep": self.episodes_done}
        if recent:
            values["return"] = f"{np.mean([e.episode_return for e in recent]):.2f}"
            values["done"] = f"{np.mean([e.outcome == 'finished' for e in recent]):.0%}"
        if self.last_eval is not None:
            values["eval"] = f"{self.last_eval['completed']}/{self.last_eval['episodes']}"
        return values

    def log_losses(self, global_step: int, **values: float) -> None:
        seconds = time.perf_counter() - self.start_time
        self.logger.log("losses", global_step, **{k: round(float(v), 6) for k, v in values.items()},
                        SPS=round((global_step - self.start_step) / max(seconds, 1e-9)))

    def elapsed(self) -> float:
        return self.elapsed_before + time.perf_counter() - self.start_time

    # -- evaluation ---------------------------------------------------------------------

    def evaluation_due(self, global_step: int) -> bool:
        return self.args.eval_every > 0 and global_step >= self.next_eval

    def evaluate(self, global_step: int, policy: nn.Module) -> dict:
        """The periodic evaluation hook: `metrics_run` on validation tracks; keeps the best actor."""
        while self.args.eval_every > 0 and self.next_eval <= global_step:
            self.next_eval += self.args.eval_every
        start = time.perf_counter()
        result = evaluate(policy, obs_dim_of(self.args), self.args.eval_episodes, self.args.eval_seed,
                          **env_options_of(self.args))
        self.eval_seconds += time.perf_counter() - start
        self.last_eval = {"global_step": global_step, **result}
        self.logger.log("eval", global_step, completed=result["completed"], episodes=result["episodes"],
                        mean_return=round(result["mean_return"], 5), mean_steps=round(result["mean_steps"], 2),
                        mean_speed=round(result["mean_speed"], 5))
        self.logger.flush()
        if self.best_eval is None or eval_key(result) > eval_key(self.best_eval):
            self.best_eval = self.last_eval
            save_state(policy.state_dict(), self.folder / "policy_best.pt")
        if self.bar is not None:
            self.bar.set_postfix(self.postfix(), refresh=False)
        return result

    # -- checkpoints --------------------------------------------------------------------

    def checkpoint_due(self, global_step: int) -> bool:
        return self.args.checkpoint_every > 0 and global_step >= self.next_checkpoint

    def save_checkpoint(self, global_step: int, state: dict) -> None:
        """Everything needed to go on: the algorithm's state dicts plus the run's own bookkeeping."""
        while self.args.checkpoint_every > 0 and self.next_checkpoint <= global_step:
            self.next_checkpoint += self.args.checkpoint_every
        run_state = {"global_step": global_step, "elapsed": self.elapsed(), "eval_seconds": self.eval_seconds,
                     "episodes_done": self.episodes_done, "best_eval": json.dumps(self.best_eval),
                     "last_eval": json.dumps(self.last_eval), "next_eval": self.next_eval,
                     "recent": json.dumps([list(e) for e in self.recent]), "rng": global_rng_state()}
        self.logger.flush()
        save_state({"run": run_state, "algorithm": state}, self.checkpoint_path)

    def load_checkpoint(self) -> tuple[int, dict]:
        """Restore the run's bookkeeping; return (global_step, the algorithm's state dicts)."""
        checkpoint = load_state(self.checkpoint_path)
        run_state = checkpoint["run"]
        step = int(run_state["global_step"])
        self.elapsed_before = float(run_state["elapsed"])
        self.eval_seconds = float(run_state["eval_seconds"])
        self.episodes_done = int(run_state["episodes_done"])
        self.best_eval = json.loads(run_state["best_eval"])
        self.last_eval = json.loads(run_state["last_eval"])
        self.next_eval = int(run_state["next_eval"])
        self.next_checkpoint = step + self.args.checkpoint_every
        self.recent.extend(EpisodeStats(*e) for e in json.loads(run_state["recent"]))
        set_global_rng_state(run_state["rng"])
        self.logger.truncate_after(step)
        return step, checkpoint["algorithm"]

    # -- the end ------------------------------------------------------------------------

    def finish(self, global_step: int, policy: nn.Module, state: dict) -> dict:
        """Final checkpoint, actor, 100-episode evaluation, summary.json and curves.png."""
        self.save_checkpoint(global_step, state)
        training_seconds = self.elapsed()
        if self.bar is not None:
            self.bar.close()
        save_state(policy.state_dict(), self.folder / "policy_final.pt")
        if not (self.folder / "policy_best.pt").exists():
            save_state(policy.state_dict(), self.folder / "policy_best.pt")
        summary = {"algorithm": self.algorithm, "seed": self.args.seed, "steps": global_step,
                   "envs": self.args.envs, "training_seconds": round(training_seconds, 1),
                   "periodic_eval_seconds": round(self.eval_seconds, 1), "episodes": self.episodes_done,
                   "best_periodic_eval": self.best_eval}
        if self.args.final_eval_episodes > 0:
            print(f"final evaluation: {self.args.final_eval_episodes} episodes, seed {FINAL_EVAL_SEED}",
                  file=sys.stderr)
            summary["final_eval"] = {
                which: evaluate(self.policy_from(which, policy), obs_dim_of(self.args), self.args.final_eval_episodes,
                                FINAL_EVAL_SEED, **env_options_of(self.args))
                for which in ("final", "best")}
        (self.folder / "summary.json").write_text(json.dumps(summary, indent=2))
        self.logger.close()
        try:
            plot_curves(self.folder)
        except Exception as error:  # a missing curve never loses a run
            print(f"warning: no training-curve PNG ({error})", file=sys.stderr)
        return summary

    def policy_from(self, which: str, policy: nn.Module) -> nn.Module:
        policy.load_state_dict(load_state(self.folder / f"policy_{which}.pt"))
        return policy

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        self.logger.close()


def prepare_folder(folder: Path, resume: bool) -> None:
    """The run folder must be writable; --resume needs a checkpoint; a new run never overwrites one."""
    checkpoint = folder / "checkpoint.pt"
    if resume:
        if not checkpoint.is_file():
            raise TrainError(f"no run to resume in {folder}: {checkpoint} does not exist")
    elif checkpoint.exists():
        raise TrainError(f"{folder} already holds a run: add --resume to continue it, or choose another --out")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise TrainError(f"cannot create the output folder {folder}: {error.strerror or error}") from error
    if not os.access(folder, os.W_OK | os.X_OK):
        raise TrainError(f"the output folder {folder} is not writable")

"""What the baselines really share: cars to collect from, a replay buffer, the Polyak update,
logging, the evaluation hook, checkpoints and the export of a deterministic actor.

Nothing algorithm-specific lives here (in the spirit of ``stable_baselines3.common``): the
networks, losses and training loops are in one file per algorithm, readable top to bottom.

A run folder (``league train ALGO --out runs/NAME``) holds::

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

import csv
import dataclasses
import json
import os
import random
import sys
import time
import warnings
from collections import deque
from pathlib import Path
from typing import Any, Iterable, NamedTuple

import numpy as np
import torch
from torch import nn

from league.env import MicroRacerEnv

NEUTRAL_ACTION = (0.0, 0.0)  # [acceleration, turn]: keep speed and heading (thesis, section 4.1)
RECENT_EPISODES = 20  # window of the progress bar's return and completion rate
EXPORT_TOLERANCE = 1e-5  # exported actions must match the torch actor's within this
FORMATS = {"onnx": ".onnx", "torchscript": ".pt"}


class TrainError(ValueError):
    """A training or export request that cannot be honoured; the message is one line for the user."""


# --------------------------------------------------------------------------- seeding


def seed_everything(seed: int) -> None:
    """The one seeding block (CleanRL): Python, NumPy and torch; the cars are seeded by `Cars`."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    torch.set_num_threads(1)  # small MLPs: one thread is fastest, and the machine is shared


# --------------------------------------------------------------------------- cars


class EpisodeStats(NamedTuple):
    episode_return: float
    steps: int  # environment steps (a neutral action is a step of its own)
    outcome: str  # finished, off_road, wrong_direction, too_slow or timeout
    mean_speed: float  # SPEC "Evaluation run": speeds of the non-final steps / steps


class CarStep(NamedTuple):
    """What `Cars.step` returns, one row per car (arrays are fresh copies)."""

    next_obs: np.ndarray  # the observation after the action (the last one when the episode ended)
    rewards: np.ndarray
    terminated: np.ndarray  # the episode ended: finished or crashed
    truncated: np.ndarray  # out of time (max_episode_steps)
    finished: np.ndarray  # the lap is complete


class Cars:
    """K independent single-car MicroRacer environments stepped together, each on its own tracks.

    A car whose episode ends is reset at once to a new random track, so every slot always
    drives: `step` returns the true next observations (for the replay buffer) and `obs` holds
    the observations to act on next. K separate cars are as fast as the batched PettingZoo
    interface for training (a step is ~3 µs against ~2 ms of gradient updates per
    transition) and see K times more tracks, where the ParallelEnv's cars share one track
    and wait for the slowest.

    The thesis (section 4.1) "randomly performs, after a chosen action, another one composed
    of [0, 0], which keeps the same speed and direction", to loosen the agent's coupling to
    the time step: with probability ``neutral_prob`` a car's decision lasts two steps, the
    second one neutral, and the transition carries the sum of both rewards.
    """

    def __init__(self, n_cars: int, seed: int | list[int], neutral_prob: float = 0.0, **env_options):
        if n_cars < 1:
            raise TrainError(f"--envs must be at least 1, got {n_cars}")
        self.envs = [MicroRacerEnv(**env_options) for _ in range(n_cars)]
        self.n = n_cars
        self.obs_dim = self.envs[0].observation_space.shape[0]
        self.neutral_prob = neutral_prob
        sequence = np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(sequence.spawn(1)[0])
        self._seeds = [int(s) for s in sequence.generate_state(n_cars)]
        self.obs = np.zeros((n_cars, self.obs_dim), dtype=np.float32)
        self._return = np.zeros(n_cars)
        self._steps = np.zeros(n_cars, dtype=np.int64)
        self._speed_sum = np.zeros(n_cars)
        self.episodes: list[EpisodeStats] = []  # finished since the last `pop_episodes`

    def reset(self) -> np.ndarray:
        for i, env in enumerate(self.envs):
            self.obs[i] = env.reset(seed=self._seeds[i])[0]
        return self.obs.copy()

    def step(self, actions: np.ndarray) -> CarStep:
        n = self.n
        next_obs = np.empty_like(self.obs)
        rewards = np.zeros(n, dtype=np.float32)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        finished = np.zeros(n, dtype=bool)
        neutral = self.rng.random(n) < self.neutral_prob
        for i, env in enumerate(self.envs):
            obs, reward, term, trunc, info = self._env_step(i, actions[i])
            if neutral[i] and not (term or trunc):
                obs, reward2, term, trunc, info = self._env_step(i, NEUTRAL_ACTION)
                reward += reward2
            next_obs[i], rewards[i], terminated[i], truncated[i] = obs, reward, term, trunc
            if term or trunc:
                finished[i] = info["outcome"] == "finished"
                self._end_episode(i, "timeout" if trunc and not term else info["outcome"])
                self.obs[i] = env.reset()[0]
            else:
                self.obs[i] = obs
        return CarStep(next_obs, rewards, terminated, truncated, finished)

    def _env_step(self, i: int, action) -> tuple:
        obs, reward, terminated, truncated, info = self.envs[i].step(action)
        self._return[i] += reward
        self._steps[i] += 1
        if not (terminated or truncated):
            self._speed_sum[i] += info["speed"]
        return obs, reward, terminated, truncated, info

    def _end_episode(self, i: int, outcome: str) -> None:
        steps = int(self._steps[i])
        self.episodes.append(EpisodeStats(float(self._return[i]), steps, outcome, float(self._speed_sum[i]) / steps))
        self._return[i], self._steps[i], self._speed_sum[i] = 0.0, 0, 0.0

    def pop_episodes(self) -> list[EpisodeStats]:
        episodes, self.episodes = self.episodes, []
        return episodes


# --------------------------------------------------------------------------- replay buffer


class ReplayBatch(NamedTuple):
    observations: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor  # (batch,)
    next_observations: torch.Tensor
    dones: torch.Tensor  # (batch,) 1.0 where the next state is terminal (no bootstrap)


class ReplayBuffer:
    """A FIFO buffer of transitions (Lin 1992; Mnih et al. 2015), sampled uniformly."""

    def __init__(self, capacity: int, obs_dim: int, act_dim: int, seed: int):
        self.capacity = capacity
        self.observations = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.next_observations = np.zeros((capacity, obs_dim), dtype=np.float32)
        self.actions = np.zeros((capacity, act_dim), dtype=np.float32)
        self.rewards = np.zeros(capacity, dtype=np.float32)
        self.dones = np.zeros(capacity, dtype=np.float32)
        self.pos = 0  # next slot to write
        self.size = 0
        self.rng = np.random.default_rng(seed)

    def add(self, obs: np.ndarray, actions: np.ndarray, rewards: np.ndarray, next_obs: np.ndarray,
            dones: np.ndarray) -> None:
        """Store a batch of transitions (one per car)."""
        for k in range(len(obs)):
            p = self.pos
            self.observations[p], self.actions[p], self.rewards[p] = obs[k], actions[k], rewards[k]
            self.next_observations[p], self.dones[p] = next_obs[k], dones[k]
            self.pos = (p + 1) % self.capacity
            self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int) -> ReplayBatch:
        idx = self.rng.integers(0, self.size, size=batch_size)
        return ReplayBatch(*(torch.from_numpy(a[idx]) for a in (self.observations, self.actions, self.rewards,
                                                                  self.next_observations, self.dones)))

    def state_dict(self) -> dict:
        n = self.size
        return {"observations": torch.from_numpy(self.observations[:n].copy()),
                "next_observations": torch.from_numpy(self.next_observations[:n].copy()),
                "actions": torch.from_numpy(self.actions[:n].copy()),
                "rewards": torch.from_numpy(self.rewards[:n].copy()),
                "dones": torch.from_numpy(self.dones[:n].copy()),
                "pos": self.pos, "rng": self.rng.bit_generator.state}

    def load_state_dict(self, state: dict) -> None:
        n = len(state["rewards"])
        for name in ("observations", "next_observations", "actions", "rewards", "dones"):
            getattr(self, name)[:n] = state[name].numpy()
        self.size, self.pos = n, int(state["pos"])
        self.rng.bit_generator.state = state["rng"]


# --------------------------------------------------------------------------- networks


@torch.no_grad()
def polyak_update(params: list[torch.Tensor], target_params: list[torch.Tensor], tau: float) -> None:
    """θ' ← τ θ + (1 − τ) θ' (Lillicrap et al. 2016, Algorithm 1), all tensors in one fused call.

    ``lerp_(θ', θ, τ)`` is exactly θ' + τ (θ − θ'); the lists are built once by the caller.
    """
    torch._foreach_lerp_(target_params, params, tau)


def adam(params: Iterable[torch.Tensor], lr: float, **kwargs) -> torch.optim.Adam:
    """Adam (Kingma and Ba 2015) with its fused CPU kernel: ~20 % faster updates for small MLPs
    than the default per-tensor loop (torch >= 2.4; the plain one before)."""
    params = list(params)
    try:
        return torch.optim.Adam(params, lr=lr, fused=True, **kwargs)
    except (RuntimeError, TypeError):
        return torch.optim.Adam(params, lr=lr, **kwargs)


def mlp(sizes: Iterable[int], activation: type[nn.Module] = nn.ReLU, output_activation: type[nn.Module] | None = None
        ) -> nn.Sequential:
    """Linear layers of the given sizes with `activation` between them (and optionally after the last)."""
    sizes = list(sizes)
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers.append(activation())
        elif output_activation is not None:
            layers.append(output_activation())
    return nn.Sequential(*layers)


class ObservationNormalizer(nn.Module):
    """(obs − mean) / std with statistics fitted once, on the warm-up data, then frozen.

    Lidar readings near a border are a few hundredths of a unit, where a hundredth matters:
    standardised inputs give the first layer the resolution it needs. The statistics are
    buffers, not parameters: saved with the weights and exported with the actor, untouched by
    the optimiser and by Polyak updates. Until fitted it is the identity.
    """

    def __init__(self, obs_dim: int):
        super().__init__()
        self.register_buffer("mean", torch.zeros(obs_dim))
        self.register_buffer("std", torch.ones(obs_dim))

    @torch.no_grad()
    def fit(self, observations: np.ndarray | torch.Tensor) -> None:
        observations = torch.as_tensor(observations, dtype=torch.float32)
        if len(observations) < 2:
            raise TrainError("observation statistics need at least 2 observations of warm-up data")
        self.mean.copy_(observations.mean(0))
        self.std.copy_(observations.std(0).clamp(min=1e-3))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return (obs - self.mean) / self.std


def fit_normalizers(networks: Iterable[nn.Module], observations: np.ndarray) -> None:
    """Fit the `obs_norm` of every network on the same observations."""
    for network in networks:
        network.obs_norm.fit(observations)


# --------------------------------------------------------------------------- logging


class Logger:
    """Scalars by section ("charts", "losses", "eval"): one CSV per section, and TensorBoard
    (``charts/episodic_return``...) when the ``tensorboard`` package is installed."""

    def __init__(self, folder: Path, tensorboard: bool = True):
        self.folder = folder
        self._files: dict[str, Any] = {}
        self._writers: dict[str, csv.DictWriter] = {}
        self.tb = None
        if tensorboard:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    from torch.utils.tensorboard import SummaryWriter
                self.tb = SummaryWriter(str(folder / "tensorboard"))
            except ImportError:  # optional: pip install tensorboard
                self.tb = None

    def log(self, section: str, step: int, **values: float | str) -> None:
        writer = self._writers.get(section)
        if writer is None:
            path = self.folder / f"{section}.csv"
            new = not path.exists() or path.stat().st_size == 0
            handle = open(path, "a", newline="")
            writer = csv.DictWriter(handle, fieldnames=["global_step", "wall_time", *values])
            if new:
                writer.writeheader()
            self._files[section], self._writers[section] = handle, writer
        writer.writerow({"global_step": step, "wall_time": round(time.time(), 3), **values})
        if self.tb is not None:
            for key, value in values.items():
                if isinstance(value, (int, float)):
                    self.tb.add_scalar(f"{section}/{key}", value, step)

    def flush(self) -> None:
        for handle in self._files.values():
            handle.flush()
        if self.tb is not None:
            self.tb.flush()

    def close(self) -> None:
        for handle in self._files.values():
            handle.close()
        self._files.clear()
        self._writers.clear()
        if self.tb is not None:
            self.tb.close()

    def truncate_after(self, step: int) -> None:
        """On resume, drop rows written after the checkpoint (they will be written again)."""
        for path in self.folder.glob("*.csv"):
            rows = read_csv(path)
            if not rows:
                continue
            with open(path, "w", newline="") as handle:
                writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
                writer.writeheader()
                writer.writerows(r for r in rows if int(float(r["global_step"])) <= step)


def read_csv(path: Path) -> list[dict]:
    if not Path(path).exists():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


# --------------------------------------------------------------------------- evaluation and export


def evaluate(policy: nn.Module, obs_dim: int, episodes: int, seed: int, **env_options) -> dict:
    """`league.evaluation.metrics_run` of the deterministic actor; the summary figures."""
    from league.agents import torch_module_agent
    from league.evaluation import metrics_run

    was_training = policy.training
    agent = torch_module_agent(policy, obs_dim=obs_dim, name="policy")
    result = metrics_run(agent, episodes=episodes, seed=seed, **env_options)
    policy.train(was_training)
    return {"completed": result.completed, "episodes": result.episodes_total, "mean_return": result.mean_return,
            "mean_steps": result.mean_steps, "mean_speed": result.mean_speed, "outcomes": result.outcome_counts()}


def export_policy(policy: nn.Module, path: str | os.PathLike, fmt: str, obs_dim: int) -> Path:
    """Write the deterministic actor as ONNX or TorchScript, load it back with
    `league.agents.load_agent` and check its actions against the torch actor's."""
    from league.agents import AgentError, export_onnx, export_torchscript, load_agent

    if fmt not in FORMATS:
        raise TrainError(f"unknown format {fmt!r}: use one of {', '.join(FORMATS)}")
    path = Path(path)
    check_writable_file(path)
    policy.eval()
    if fmt == "onnx":
        export_onnx(policy, path, obs_dim=obs_dim)
    else:
        export_torchscript(policy, path)
    try:
        agent = load_agent(path, obs_dim=obs_dim)
    except AgentError as error:
        raise TrainError(f"the exported {fmt} file does not load: {error.reason}") from error
    obs = probe_observations(obs_dim)
    with torch.no_grad():
        expected = policy(torch.from_numpy(obs)).numpy()
    error = float(np.max(np.abs(agent(obs) - np.clip(expected, -1, 1))))
    if error > EXPORT_TOLERANCE:
        raise TrainError(f"the exported {fmt} actor differs from the torch actor by {error:.2e}")
    return path


def probe_observations(obs_dim: int, batch: int = 256, seed: int = 0) -> np.ndarray:
    """Plausible observations: from a short random drive, plus uniform noise around them."""
    env = MicroRacerEnv(observation="compact" if obs_dim == 5 else "lidar")
    rng = np.random.default_rng(seed)
    rows = []
    obs, _ = env.reset(seed=seed)
    while len(rows) < batch // 2:
        obs, _, terminated, truncated, _ = env.step(np.array([rng.uniform(-0.2, 1), rng.uniform(-0.3, 0.3)],
                                                             dtype=np.float32))
        rows.append(obs)
        if terminated or truncated:
            obs, _ = env.reset()
    rows = np.array(rows, dtype=np.float32)
    noisy = rows * rng.uniform(0.5, 1.5, rows.shape).astype(np.float32)
    return np.concatenate([rows, noisy]).astype(np.float32)


def check_writable_file(path: Path) -> None:
    folder = path.resolve().parent
    if not folder.is_dir():
        raise TrainError(f"cannot write {path}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise TrainError(f"cannot write {path}: the folder {folder} is not writable")


# --------------------------------------------------------------------------- the run


def save_state(state: dict, path: Path) -> None:
    """torch.save of our own state dicts, written atomically (an interrupted save keeps the old file)."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)


def load_state(path: Path) -> dict:
    """Load a file written by `save_state`: tensors and plain data only (weights_only: no pickled code)."""
    return torch.load(path, map_location="cpu", weights_only=True)


def args_to_dict(args: Any) -> dict:
    return dataclasses.asdict(args)


class Run:
    """A training run: its folder, logger, progress bar, periodic evaluation and checkpoints.

    The algorithm's loop calls `record(global_step, episodes)` after each iteration,
    `log_losses(...)` now and then, and `checkpoint_due` / `save_checkpoint`; `finish` writes
    the final actor, the summary and the curves.
    """

    def __init__(self, folder: str | os.PathLike, algorithm: str, args: Any, *, resume: bool = False,
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
        config = {"algorithm": self.algorithm, "args": args_to_dict(self.args), "obs_dim": obs_dim_of(self.args),
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
                     "recent": json.dumps([list(e) for e in self.recent]),
                     "rng": {"python": json.dumps(random.getstate()), "numpy": json.dumps(np_legacy_state()),
                             "torch": torch.get_rng_state()}}
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
        random.setstate(tuple(tuple(x) if isinstance(x, list) else x for x in json.loads(run_state["rng"]["python"])))
        np_set_legacy_state(json.loads(run_state["rng"]["numpy"]))
        torch.set_rng_state(run_state["rng"]["torch"])
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


FINAL_EVAL_SEED = 0  # the final 100-episode evaluation uses `league evaluate`'s default tracks


def eval_key(result: dict) -> tuple:
    """Which periodic evaluation is best: the highest racing score, completed fraction × mean
    speed (a league race is won by finishing, fast), then the higher mean return.

    Ranking by completed laps alone keeps the slowest cautious actor; by speed alone, a reckless one.
    """
    return result["completed"] / result["episodes"] * result["mean_speed"], result["mean_return"]


def np_legacy_state() -> list:
    name, keys, pos, has_gauss, cached = np.random.get_state()
    return [name, keys.tolist(), int(pos), int(has_gauss), float(cached)]


def np_set_legacy_state(state: list) -> None:
    name, keys, pos, has_gauss, cached = state
    np.random.set_state((name, np.array(keys, dtype=np.uint32), pos, has_gauss, cached))


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


def obs_dim_of(args: Any) -> int:
    return 5 if args.observation == "compact" else 20


def env_options_of(args: Any) -> dict:
    """The environment options of a run (evaluations use the same, with the agent's observation)."""
    return {"obstacles": args.obstacles, "chicanes": args.chicanes, "turn_limit": args.turn_limit,
            "low_speed_termination": args.low_speed_termination}


def make_cars(args: Any, seed_offset: int = 0) -> Cars:
    """The training cars of a run; a resumed run (`seed_offset` = its step) draws new tracks."""
    seed = args.seed if seed_offset == 0 else [args.seed, seed_offset]
    return Cars(args.envs, seed, args.neutral_prob, observation=args.observation, **env_options_of(args))


# --------------------------------------------------------------------------- curves


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


# --------------------------------------------------------------------------- arguments shared by every algorithm


@dataclasses.dataclass
class CommonArgs:
    """Arguments every baseline has; each algorithm's `Args` adds its hyperparameters."""

    seed: int = 1
    """seed of the networks, the exploration and the training tracks"""
    steps: int = 50_000
    """training iterations: environment transitions collected (off-policy: one gradient update each)"""
    envs: int = 1
    """cars collecting at once, each on its own tracks (K transitions per iteration)"""
    observation: str = "compact"
    """what the agent sees: 'compact' (5 numbers, as the thesis) or 'lidar' (19 rays + speed)"""
    neutral_prob: float = 0.1
    """probability of the thesis' neutral [0, 0] action after a chosen one (training only)"""
    obstacles: bool = True
    """obstacles on the training tracks"""
    chicanes: bool = True
    """a chicane on the training tracks"""
    turn_limit: bool = True
    """speed-dependent turn limit"""
    low_speed_termination: bool = True
    """end episodes below speed 0.05"""
    eval_every: int = 5_000
    """evaluate the deterministic actor every this many steps (0: never)"""
    eval_episodes: int = 50
    """episodes of each periodic evaluation (validation tracks, seed eval_seed)"""
    eval_seed: int = 12345
    """seed of the periodic evaluations' tracks (the final evaluation uses seed 0)"""
    final_eval_episodes: int = 100
    """episodes of the final evaluation on `league evaluate`'s tracks (seed 0); 0 to skip"""
    checkpoint_every: int = 10_000
    """save a resumable checkpoint every this many steps (0: only at the end)"""
    log_every: int = 500
    """write losses every this many steps"""
    normalize_obs: bool = True
    """standardise observations with statistics of the warm-up data (frozen, exported with the actor)"""


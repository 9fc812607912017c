"""The export of a deterministic actor to ONNX or TorchScript, checked against the torch actor."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import torch
from torch import nn

from league.agents import AgentError, export_onnx, export_torchscript, load_agent
from league.baselines.common.args import TrainError
from league.constants import observation_name
from league.env import MicroRacerEnv

EXPORT_TOLERANCE = 1e-5  # exported actions must match the torch actor's within this
FORMATS = {"onnx": ".onnx", "torchscript": ".pt"}


def export_policy(policy: nn.Module, path: str | os.PathLike, fmt: str, obs_dim: int) -> Path:
    """Write the deterministic actor as ONNX or TorchScript, load it back with
    `league.agents.load_agent` and check its actions against the torch actor's."""
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
    env = MicroRacerEnv(observation=observation_name(obs_dim))
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


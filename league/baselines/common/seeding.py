"""Seeding, and the states of the global random generators that a checkpoint carries."""
from __future__ import annotations

import json
import random

import numpy as np
import torch


def seed_everything(seed: int) -> None:
    """The one seeding block (CleanRL): Python, NumPy and torch; the cars are seeded by `Cars`."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    torch.set_num_threads(1)  # small MLPs: one thread is fastest, and the machine is shared


def global_rng_state() -> dict:
    """Python's, NumPy's and torch's global generators, as data `torch.load(weights_only=True)` reads."""
    name, keys, pos, has_gauss, cached = np.random.get_state()
    numpy_state = [name, keys.tolist(), int(pos), int(has_gauss), float(cached)]
    return {"python": json.dumps(random.getstate()), "numpy": json.dumps(numpy_state),
            "torch": torch.get_rng_state()}


def set_global_rng_state(state: dict) -> None:
    """Restore what `global_rng_state` returned."""
    random.setstate(tuple(tuple(x) if isinstance(x, list) else x for x in json.loads(state["python"])))
    name, keys, pos, has_gauss, cached = json.loads(state["numpy"])
    np.random.set_state((name, np.array(keys, dtype=np.uint32), pos, has_gauss, cached))
    torch.set_rng_state(state["torch"])

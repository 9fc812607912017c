"""Scalars of a run by section: one CSV file per section, and TensorBoard when installed."""
from __future__ import annotations

import csv
import time
import warnings
from pathlib import Path
from typing import Any


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

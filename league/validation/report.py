"""A validation's verdict, as the server records it and `league check` prints it."""
from __future__ import annotations

from dataclasses import dataclass

from league.validation.probes import Probe


@dataclass(frozen=True)
class ValidationReport:
    ok: bool
    obs_dim: int | None
    error: str | None  # why the model is refused, for the student
    log: str  # what the model's runtime printed
    cpu_ms_per_observation: float | None = None
    probe: Probe | None = None  # its actions on the probe set (the server's validation records them)

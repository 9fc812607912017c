"""The source tree, and `python -m league.server` as a shell runs it."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from ..layout import REPO



def server_command(cwd: Path, *args: str, **env: str) -> subprocess.CompletedProcess:
    """`python -m league.server ARGS` in `cwd`, with no LEAGUE_* variable but `env`'s (as a shell
    without the test settings)."""
    clean = {name: value for name, value in os.environ.items() if not name.upper().startswith("LEAGUE_")}
    return subprocess.run([sys.executable, "-m", "league.server", *args], cwd=cwd, capture_output=True, text=True,
                          env={**clean, "PYTHONPATH": str(REPO), **env}, timeout=120)

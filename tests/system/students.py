"""The `league` command as a student runs it against the system tests' servers: its own config
directory and environment (test_client.py, test_student_install.py)."""
from __future__ import annotations

import os
import subprocess
import sys

from ..server.commands import REPO


def league(*args: str, config, **env: str) -> subprocess.CompletedProcess:
    """`league ARGS` as a student runs it: its own config directory, no LEAGUE_* server settings
    but the ones given."""
    return subprocess.run([sys.executable, "-m", "league.cli", *args], cwd=config, env=student_env(config, **env),
                          capture_output=True, text=True, timeout=300)


def student_env(config, **env: str) -> dict:
    base = {k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")}
    return {**base, "XDG_CONFIG_HOME": str(config), "PYTHONPATH": str(REPO), **env}

"""The `league` command as a student runs it against the system tests' servers: its own config
directory and environment, a student's token, names that do not collide (test_client.py,
test_student_install.py)."""
from __future__ import annotations

import os
import subprocess
import sys
import uuid

from ..server.conftest import REPO


def unique(name: str) -> str:
    return f"{name}-{uuid.uuid4().hex[:6]}"


def league(*args: str, config, **env: str) -> subprocess.CompletedProcess:
    """`league ARGS` as a student runs it: its own config directory, no LEAGUE_* server settings
    but the ones given."""
    return subprocess.run([sys.executable, "-m", "league.cli", *args], cwd=config, env=student_env(config, **env),
                          capture_output=True, text=True, timeout=300)


def student_env(config, **env: str) -> dict:
    base = {k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")}
    return {**base, "XDG_CONFIG_HOME": str(config), "PYTHONPATH": str(REPO), **env}


def student_token(server, name: str) -> str:
    with server.client(server.instructor_token) as instructor:
        response = instructor.post("/api/users", json={"name": name})
    assert response.status_code == 201, response.text
    return response.json()["token"]

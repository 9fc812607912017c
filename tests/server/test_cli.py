"""`league users ...` and the server commands in the toolkit's `league` CLI."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from league.cli import build_parser

REPO = Path(__file__).resolve().parents[2]


def league(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "league.cli", *args], env=env, cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)


def test_league_cli_has_the_server_commands():
    parser = build_parser()
    assert parser.parse_args(["serve", "--host", "0.0.0.0", "--port", "9000"]).port == 9000
    assert parser.parse_args(["worker", "--threads", "2"]).threads == 2
    assert parser.parse_args(["users", "add", "ann", "--role", "student"]).role == "student"


def test_users_add_prints_a_token_once_and_names_are_unique(tmp_path):
    added = league(tmp_path, "users", "add", "prof", "--role", "instructor")
    assert added.returncode == 0, added.stderr
    token = added.stdout.strip()
    assert token.startswith("lg_") and len(token) > 40
    stored = b"".join(p.read_bytes() for p in tmp_path.glob("league.db*"))
    assert token.encode() not in stored  # only its sha256 is kept

    again = league(tmp_path, "users", "add", "prof", "--role", "student")
    assert again.returncode == 1
    assert "user name 'prof' is already taken" in again.stderr

    assert league(tmp_path, "users", "revoke", "prof").returncode == 0
    listing = league(tmp_path, "users", "list").stdout
    assert "prof" in listing and "revoked" in listing

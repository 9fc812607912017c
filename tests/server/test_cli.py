"""`league users ...` and the server commands in the toolkit's `league` CLI."""
from __future__ import annotations

import os
import subprocess
import sys
import time
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

    student = league(tmp_path, "users", "add", "ann")  # student: the default role
    assert student.returncode == 0, student.stderr
    assert "created student 'ann'" in student.stderr

    assert league(tmp_path, "users", "revoke", "prof").returncode == 0
    listing = league(tmp_path, "users", "list").stdout
    assert "prof" in listing and "revoked" in listing
    assert [line.split()[1:3] for line in listing.splitlines() if " ann " in line] == [["ann", "student"]]


def test_a_worker_runs_its_threads_on_the_cpus_it_is_given(tmp_path):
    cpu = str(min(os.sched_getaffinity(0)))
    log = tmp_path / "worker.log"
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    with open(log, "wb") as output:
        worker = subprocess.Popen([sys.executable, "-m", "league.cli", "worker", "--cpus", cpu], env=env, cwd=tmp_path,
                                  stdout=output, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while "consumer started" not in log.read_text().lower():  # its job threads run by now
            assert worker.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        threads = list(Path(f"/proc/{worker.pid}/task").iterdir())
        allowed = {(task / "status").read_text().split("Cpus_allowed_list:")[1].split()[0] for task in threads}
    finally:
        worker.terminate()
        worker.wait(timeout=30)
    assert f"running on CPUs {cpu}" in log.read_text()
    assert len(threads) > 1 and allowed == {cpu}


def test_a_worker_refuses_cpus_it_cannot_have(tmp_path):
    missing = league(tmp_path, "worker", "--cpus", "4096")
    assert missing.returncode == 2
    assert "--cpus '4096': CPU 4096 is not available here (this process may run on" in missing.stderr
    backwards = league(tmp_path, "worker", "--cpus", "3-1")
    assert backwards.returncode == 2
    assert "'3-1' is not a CPU number or range such as 2 or 0-3" in backwards.stderr

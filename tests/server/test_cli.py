"""`league users ...` and the server commands in the toolkit's `league` CLI."""
from __future__ import annotations

import csv
import io
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from league.cli import build_parser

from .conftest import create_student, fresh_backend, make_server, submission, upload, wait_for

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
    assert league(tmp_path, "init").returncode == 0
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


def test_users_import_creates_a_rosters_students_and_prints_their_tokens(tmp_path):
    """`league users import` reads rosters as the API does: the good lines' tokens as CSV on stdout,
    each other line with its number on stderr, exit 1 while a line has an error."""
    roster = tmp_path / "roster.csv"
    roster.write_bytes("\ufeffVorname;Nachname;E-Mail;Matrikelnummer\r\nNiaj;O'Brien;niaj@uni.de;0042\r\n"
                       "Zoë;Müller;zoe@uni;0043\r\n".encode())
    assert league(tmp_path, "init").returncode == 0
    first = league(tmp_path, "users", "import", str(roster))
    assert first.returncode == 1, first.stderr
    assert first.stdout.splitlines()[0] == "name,email,student_id,token"
    assert first.stdout.splitlines()[1].startswith('"Niaj O\'Brien","niaj@uni.de","0042","lg_')  # league.spreadsheet's
    created = list(csv.reader(io.StringIO(first.stdout)))[1:]
    assert [row[:3] for row in created] == [["Niaj O'Brien", "niaj@uni.de", "0042"]] and created[0][3].startswith("lg_")
    assert first.stderr.splitlines()[1:] == [  # after the line naming the database
        "line 3: error: the email 'zoe@uni' is not an address: The part after the @-sign is not valid. "
        "It should have a period.",
        "created 1 student, skipped 0 lines, 1 line with errors; the tokens above are shown once"]

    roster.write_bytes("Vorname;Nachname;E-Mail;Matrikelnummer\nNiaj;O'Brien;;0042\nZoë;Müller;zoe@uni.de;0043\n".encode())
    second = league(tmp_path, "users", "import", str(roster))
    assert second.returncode == 0, second.stderr
    assert [row[:3] for row in csv.reader(io.StringIO(second.stdout))] == [
        ["name", "email", "student_id"], ["Zoë Müller", "zoe@uni.de", "0043"]]
    assert second.stderr.splitlines()[1] == "line 2: skipped Niaj O'Brien: already a student (same student id)"
    missing = league(tmp_path, "users", "import", str(tmp_path / "nothing.csv"))
    assert missing.returncode == 1 and "nothing.csv: [Errno 2] No such file or directory" in missing.stderr


def test_a_worker_runs_its_threads_on_the_cpus_it_is_given(tmp_path):
    cpu = str(min(os.sched_getaffinity(0)))
    log = tmp_path / "worker.log"
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    assert league(tmp_path, "init").returncode == 0
    with open(log, "wb") as output:
        worker = subprocess.Popen([sys.executable, "-m", "league.cli", "worker", "--cpus", cpu], env=env, cwd=tmp_path,
                                  stdout=output, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while "worker started" not in log.read_text():  # its job threads run by now
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


# --------------------------------------------------------------------------- `league serve` and its worker process


def process_table() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, start time) of every live process (zombies are over: left out)."""
    table = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:  # ended meanwhile
                continue
            if fields[0] != "Z":
                table[int(entry.name)] = (int(fields[1]), fields[19])
    return table


def descendants(pid: int, table: dict[int, tuple[int, str]] | None = None) -> dict[int, str]:
    """pid -> start time of every process below `pid` (in `table`, a snapshot: default a new one)."""
    table, found, frontier = table or process_table(), {}, [pid]
    while frontier:
        parent = frontier.pop()
        for child, (ppid, started) in table.items():
            if ppid == parent and child not in found:
                found[child] = started
                frontier.append(child)
    return found


def still_running(processes: dict[int, str]) -> list[int]:
    table = process_table()
    return [pid for pid, started in processes.items() if pid in table and table[pid][1] == started]


def cmdline(pid: int) -> list[str]:
    """Its command line ([] once it has ended: a short-lived probe may end while we look)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode().rstrip("\0").split("\0")
    except OSError:
        return []


@pytest.mark.slow
@pytest.mark.parametrize("signal_", ["SIGTERM", "SIGKILL"])
def test_serve_runs_its_worker_as_a_child_process_and_nothing_outlives_it(tmp_path, models, signal_):
    """The API's process runs no job (its event loop never waits for a job's GIL): its worker is a
    `league worker` child, whose sandboxes run below it; stopping serve (or killing it) stops them all."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_EVAL_EPISODES="40")
        server.start_api()
        try:
            student = create_student(server, "kid")
            submission_id = upload(student, models["onnx"]).json()["id"]
            wait_for(lambda: (submission(student, submission_id)["evaluation"] or {}).get("status"),
                     lambda status: status == "running", timeout=60)
            table = process_table()  # one snapshot: a short-lived child may end meanwhile
            below = descendants(server.api.pid, table)
            children = [pid for pid in below if table[pid][0] == server.api.pid]
            workers = [pid for pid in children if cmdline(pid)[-2:] == ["league.server", "worker"]]
            assert len(workers) == 1, [cmdline(pid) for pid in children]  # (the other: the isolation probe's)
            below_worker = descendants(workers[0], table)  # fork servers, and the sandboxes they forked
            sandboxes = [pid for pid in below_worker if table[pid][0] != workers[0]]
            assert len(sandboxes) >= 1  # the worker's sandbox processes, evaluating
            # Jobs yield the CPU to the API: the worker's and its sandboxes' scheduling groups (a sandbox
            # shares its fork server's) at nice 10.
            assert autogroup_nice(workers[0]) == 10
            assert {autogroup_nice(pid) for pid in sandboxes} - {None} == {10}
            assert autogroup_nice(server.api.pid) < 10
            assert threading_free_of_jobs(server.api.pid)
            server.stop(server.api, kill=signal_ == "SIGKILL")
            left = wait_for(lambda: still_running(below), lambda pids: pids == [], timeout=30, interval=0.2)
        finally:
            server.stop_all()
    assert left == []
    if signal_ == "SIGTERM":
        assert server.api.returncode == 0


def autogroup_nice(pid: int) -> int | None:
    """The nice value of the scheduling group (autogroup) of a process's session; None once it has ended.
    A process of the boot session (as under CI, where no login made a session) is in the root group,
    which the kernel weighs at nice 0: its file is empty."""
    try:
        fields = Path(f"/proc/{pid}/autogroup").read_text().split()  # "/autogroup-42 nice 10", or nothing
    except OSError:
        return None
    return int(fields[-1]) if fields else 0


def threading_free_of_jobs(pid: int) -> bool:
    """No job thread in the API's process: the worker's threads are named league-."""
    names = [(task / "comm").read_text().strip() for task in Path(f"/proc/{pid}/task").iterdir()]
    return not any(name.startswith("league-") for name in names)

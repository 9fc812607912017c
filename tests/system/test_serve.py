"""`league serve` as users start it: its worker is a child process at a lower priority, its own
process runs no job, and nothing it started outlives it, stopped or killed."""
from __future__ import annotations

from pathlib import Path

import pytest

from ..server.api_calls import create_student, submission, upload, wait_for
from ..server.backends import fresh_backend
from .servers import make_server


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
            # A snapshot of the processes (a short-lived child may end meanwhile), taken again until the
            # evaluation's sandbox shows (on a loaded machine it may not be forked yet).
            below, workers, sandboxes = wait_for(lambda: processes_of(server.api.pid), lambda found: found[2],
                                                 timeout=60, interval=0.2)
            assert len(workers) == 1, [cmdline(pid) for pid in workers]
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


def processes_of(api: int) -> tuple[dict[int, str], list[int], list[int]]:
    """What runs below serve, its worker children (the other child: the isolation probe's) and the
    processes its worker's fork servers forked (the sandboxes)."""
    table = process_table()
    below = descendants(api, table)
    workers = [pid for pid in below if table[pid][0] == api and cmdline(pid)[-2:] == ["league.server", "worker"]]
    below_worker = descendants(workers[0], table) if workers else {}  # fork servers, and their sandboxes
    return below, workers, [pid for pid in below_worker if table[pid][0] != workers[0]]


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

"""A `league worker` as users start it: the CPUs its threads run on, and what its job threads prepare
before their first job."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from ..server.api_calls import wait_for
from ..server.backends import fresh_backend
from ..server.commands import REPO, server_command
from .servers import make_server


def fork_servers(worker: int) -> list[int]:
    """The fork servers the worker started (child.py --fork-server), its direct children."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1]) if entry.name.isdigit() else 0
            command = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:  # ended meanwhile
            continue
        if parent == worker and b"--fork-server" in command:
            found.append(int(entry.name))
    return found


def served_runtime(pid: int) -> str:
    """The runtime a fork server serves: the argument after its control socket's fd."""
    command = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    return command[command.index(b"--fork-server") + 2].decode()


def has_torch(pid: int) -> bool:
    return "libtorch_cpu" in Path(f"/proc/{pid}/maps").read_text()


def test_a_new_workers_job_threads_prepare_torch_before_their_first_job(tmp_path):
    """Each job thread starts its fork servers when the worker starts, one per runtime, at the jobs'
    nice value, and the TorchScript one prepares torch (a tiny model, run) while no job asks: the
    first TorchScript model a new worker sees waits for no import of torch (35 s of a first
    upload's 47.8 s on a busy machine, issue 25). The ONNX one holds no torch (an ONNX sandbox
    forked from it starts faster). The isolation probe's own fork servers are gone."""
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url, LEAGUE_WORKER_THREADS="2", LEAGUE_JOB_NICE="10")
        worker = server.start_worker()
        try:
            servers = wait_for(lambda: fork_servers(worker.pid),
                               lambda pids: len(pids) == 4 and sum(map(has_torch, pids)) == 2, timeout=240)
            runtimes = sorted(served_runtime(pid) for pid in servers)
            nice = {int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[16]) for pid in servers}
            threads = {len(list(Path(f"/proc/{pid}/task").iterdir())) for pid in servers}
        finally:
            server.stop_all()
    assert runtimes == [".onnx", ".onnx", ".pt", ".pt"]
    assert nice == {10}  # their sandboxes inherit it
    assert threads == {1}  # prepared, still forkable: torch and onnxruntime started no thread


def test_a_worker_runs_its_threads_on_the_cpus_it_is_given(tmp_path):
    """`league worker --cpus N` of the toolkit's CLI: every thread of the worker on CPU N."""
    cpu = str(min(os.sched_getaffinity(0)))
    log = tmp_path / "worker.log"
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    assert server_command(tmp_path, "init", LEAGUE_DATA_DIR=str(tmp_path)).returncode == 0
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

"""Workers on other hosts: each `league worker` runs in a network namespace of its own (its own veth,
data directory, temporary directory and CPU slots) and reaches the league's PostgreSQL, which is
also its job queue, over the veth addresses only: the test starts one, bound to the API host's
address on a bridge (the machine's own services listen on loopback, which a namespace cannot reach).

Uploads are evaluated and a championship round is raced across the hosts; one host's link is cut
mid-heat, its heat is raced again by the other host, and once the link is back the cut host's late
result is refused: no job lost, stuck or counted twice.

Needs root, `ip netns` (iproute2), PostgreSQL's `initdb`/`postgres` run as the `postgres` system
user; skipped with the reason where one is missing.
"""
from __future__ import annotations

import contextlib
import os
import pwd
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from league.agents import load_agent
from league.evaluation import metrics_run, race

from ..server.api_calls import wait_for
from ..server.backends import TEST_SETTINGS
from .network import ip, require_namespaces, unused_prefix
from .rounds import (
    LONG_HEATS, ONE_AT_A_TIME, ROUND_SETTINGS, check_round_counted_once, enter_students, race_jobs, read_round,
    standings, start_round, wait_idle, wait_round_over, worker_pid,
)
from .servers import LeagueServer, make_server

SERVICE_USER = "postgres"  # PostgreSQL refuses to run as root
PG_PORT = 5432
HOSTS = 2
RACING = "cars: sandboxes started"  # a worker's log line as a race begins

pytestmark = pytest.mark.hosts


# --------------------------------------------------------------------------- the network


@dataclass
class Network:
    """A bridge on this host (the API's and the database's address) and one network
    namespace per worker host, joined to the bridge by a veth pair."""

    tag: str
    prefix: str  # the /24: "10.x.y"
    namespaces: list[str]

    @property
    def bridge(self) -> str:
        return f"lg{self.tag}br"

    @property
    def address(self) -> str:
        return f"{self.prefix}.1"

    @property
    def subnet(self) -> str:
        return f"{self.prefix}.0/24"

    def link(self, k: int) -> str:
        """Worker host k's veth end on this host: setting it down cuts the host off."""
        return f"lg{self.tag}h{k}"

    def run_in(self, k: int) -> tuple[str, ...]:
        return ("ip", "netns", "exec", self.namespaces[k])

    def cut(self, k: int) -> None:
        ip("link", "set", self.link(k), "down")

    def restore(self, k: int) -> None:
        ip("link", "set", self.link(k), "up")

    def reachable(self, k: int, address: str, port: int) -> bool:
        """Whether worker host k can open a TCP connection to address:port."""
        probe = f"import socket; socket.create_connection(({address!r}, {port}), timeout=2).close()"
        return subprocess.run([*self.run_in(k), sys.executable, "-c", probe], capture_output=True,
                              timeout=30).returncode == 0


@contextlib.contextmanager
def network(hosts: int) -> Iterator[Network]:
    """The bridge and the worker hosts' namespaces; all removed at the end, whatever happened."""
    require_namespaces()
    tag = uuid.uuid4().hex[:6]
    net = Network(tag, unused_prefix(), [f"league-{tag}-{k}" for k in range(hosts)])
    try:
        ip("netns", "add", net.namespaces[0])
    except subprocess.CalledProcessError as error:
        pytest.skip(f"`ip netns add` is not permitted here: {error.stderr.strip()}")
    try:
        ip("link", "add", net.bridge, "type", "bridge")
        ip("addr", "add", f"{net.address}/24", "dev", net.bridge)
        ip("link", "set", net.bridge, "up")
        for k, namespace in enumerate(net.namespaces):
            if k:
                ip("netns", "add", namespace)
            inside = f"lg{tag}w{k}"
            ip("link", "add", net.link(k), "type", "veth", "peer", "name", inside, "netns", namespace)
            ip("link", "set", net.link(k), "master", net.bridge, "up")
            ip("-n", namespace, "addr", "add", f"{net.prefix}.{k + 2}/24", "dev", inside)
            ip("-n", namespace, "link", "set", inside, "up")
            ip("-n", namespace, "link", "set", "lo", "up")
        yield net
    finally:
        for namespace in net.namespaces:  # deleting a namespace deletes its veth pair
            subprocess.run(["ip", "netns", "del", namespace], capture_output=True, timeout=30)
        subprocess.run(["ip", "link", "del", net.bridge], capture_output=True, timeout=30)


# --------------------------------------------------------------------------- PostgreSQL


@contextlib.contextmanager
def services(net: Network) -> Iterator[str]:
    """A PostgreSQL cluster (initdb in a temporary directory) listening on the bridge address only,
    run by the unprivileged SERVICE_USER; yields its database_url and stops and removes it at the end."""
    missing = [tool for tool in ("initdb", "postgres") if shutil.which(tool) is None]
    if missing:
        pytest.skip(f"not installed: {', '.join(missing)}")
    try:
        owner = pwd.getpwnam(SERVICE_USER)
    except KeyError:
        pytest.skip(f"no {SERVICE_USER!r} system user to run PostgreSQL as")
    root = Path(tempfile.mkdtemp(prefix="league-hosts-"))
    os.chown(root, owner.pw_uid, owner.pw_gid)
    as_owner = {"user": owner.pw_uid, "group": owner.pw_gid, "extra_groups": [], "cwd": root}
    processes: list[subprocess.Popen] = []
    try:
        data = root / "pgdata"
        subprocess.run(["initdb", "-D", str(data), "-U", "postgres", "--auth=trust", "--no-sync", "-E", "UTF8"],
                       check=True, capture_output=True, timeout=120, **as_owner)
        with open(data / "pg_hba.conf", "a") as hba:
            hba.write(f"host all all {net.subnet} trust\n")
        log = open(root / "services.log", "ab")
        processes.append(subprocess.Popen(
            ["postgres", "-D", str(data), "-c", f"listen_addresses={net.address}", "-c", f"port={PG_PORT}",
             "-c", f"unix_socket_directories={root}", "-c", "fsync=off"],
            stdout=log, stderr=subprocess.STDOUT, **as_owner))
        admin = f"postgresql://postgres@{net.address}:{PG_PORT}/postgres"
        wait_for(lambda: services_up(processes, admin, root / "services.log"), bool, timeout=60)
        import psycopg

        with psycopg.connect(admin, autocommit=True) as connection:
            connection.execute("CREATE DATABASE league")
        yield f"postgresql+psycopg://postgres@{net.address}:{PG_PORT}/league"
    finally:
        for process in processes:  # SIGINT: PostgreSQL's fast shutdown
            process.send_signal(signal.SIGINT)
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        shutil.rmtree(root, ignore_errors=True)


def services_up(processes: list[subprocess.Popen], admin_url: str, log: Path) -> bool:
    import psycopg

    if any(p.poll() is not None for p in processes):
        pytest.fail(f"PostgreSQL exited:\n{log.read_text(errors='replace')[-3000:]}")
    try:
        psycopg.connect(admin_url, connect_timeout=2).close()
    except psycopg.OperationalError:
        return False
    return True


# --------------------------------------------------------------------------- worker hosts


def start_host_worker(server: LeagueServer, net: Network, k: int, root: Path) -> subprocess.Popen:
    """`league worker` in host k's namespace, with a data directory, a temporary directory and CPU
    slots of its own (nothing on disk shared with the API or the other host)."""
    home = root / f"host-{k}"
    for name in ("data", "tmp", "cpu-slots"):
        (home / name).mkdir(parents=True)
    return server.start_worker(net.run_in(k), LEAGUE_DATA_DIR=str(home / "data"), TMPDIR=str(home / "tmp"),
                               LEAGUE_CPU_SLOTS_DIR=str(home / "cpu-slots"),
                               **ONE_AT_A_TIME)  # one heat at a time: who raced what is known


def worker_log(server: LeagueServer, k: int) -> str:
    return (server.data_dir / f"worker-{k}.log").read_text(errors="replace")


def consuming(server: LeagueServer, k: int) -> bool:
    """Worker k's job threads are running (they claim from the database from now on)."""
    if server.workers[k].poll() is not None:
        pytest.fail(f"worker {k} exited:\n{worker_log(server, k)[-3000:]}")
    return "worker started" in worker_log(server, k)


def all_jobs(server: LeagueServer) -> list[dict]:
    with server.client(server.instructor_token) as instructor:
        response = instructor.get("/api/jobs", params={"limit": 1000})
    assert response.status_code == 200, response.text
    return response.json()


def submissions_of(server: LeagueServer, ids: list[int]) -> dict[int, dict]:
    with server.client(server.instructor_token) as instructor:
        return {i: instructor.get(f"/api/submissions/{i}").json() for i in ids}


# --------------------------------------------------------------------------- the test


def test_workers_on_other_hosts_share_the_league_and_survive_a_cut_link(tmp_path, drivers):
    with contextlib.ExitStack() as stack:
        net = stack.enter_context(network(HOSTS))
        database_url = stack.enter_context(services(net))
        server = make_server(tmp_path, database_url, LEAGUE_BOOTSTRAP="false",
                             **ROUND_SETTINGS)
        stack.callback(server.stop_all)
        server.start_api(embedded_worker=False)
        for k in range(HOSTS):
            start_host_worker(server, net, k, tmp_path)
        # the hosts reach the league's services over the veth only, not the machine's own on loopback
        assert all(net.reachable(k, net.address, PG_PORT) for k in range(HOSTS))
        assert not any(net.reachable(k, "127.0.0.1", PG_PORT) for k in range(HOSTS))
        wait_for(lambda: all(consuming(server, k) for k in range(HOSTS)), bool, timeout=60)
        pids = [worker.pid for worker in server.workers]

        files = dict(zip(enter_students(server, drivers[:4]), drivers))  # uploads validated and evaluated
        wait_idle(server)
        entered = submissions_of(server, list(files))
        entry_jobs = all_jobs(server)

        championship_id, started = start_round(server, heat_size=2, include_baselines=False, env_options=LONG_HEATS)
        race_ids = started["race_ids"]
        assert len(race_ids) == HOSTS
        running = wait_for(lambda: race_jobs(server, race_ids),
                           lambda jobs: sum(j["status"] == "running" for j in jobs) == HOSTS, timeout=60, interval=0.05)
        cut_job = next(j for j in running if worker_pid(j) == pids[0])
        wait_for(lambda: RACING in worker_log(server, 0), bool, timeout=60, interval=0.02)  # cars on the track
        net.cut(0)  # mid-heat: host 0 races on, but can no longer heartbeat nor write its result
        [during] = [j for j in race_jobs(server, race_ids) if j["id"] == cut_job["id"]]
        assert (during["status"], during["attempts"]) == ("running", 1), during  # the cut came before the end
        finished = wait_round_over(server, championship_id)
        races, jobs = check_round_counted_once(server, championship_id, finished, list(files))
        table = standings(server, championship_id)

        net.restore(0)  # host 0 comes back: whatever it does with its stale heat must change nothing
        alive = [worker.poll() is None for worker in server.workers]  # a cut link stops no worker
        server.workers[0].send_signal(signal.SIGINT)  # graceful: its job ends (if it still runs), then it exits
        assert server.workers[0].wait(timeout=90) == 0, worker_log(server, 0)[-3000:]
        after = {"round": read_round(server, championship_id), "jobs": all_jobs(server),
                 "standings": standings(server, championship_id)}
        log_of_cut_host = worker_log(server, 0)
    # (everything stopped and removed: the workers, the API, PostgreSQL, the namespaces)

    # uploads: validated and evaluated once each, by both hosts, with the models fetched from the database
    assert all(s["status"] == "ready" and s["evaluation"]["status"] == "done" for s in entered.values()), entered
    for submission_id, path in files.items():
        local = metrics_run(load_agent(path), episodes=int(ROUND_SETTINGS["LEAGUE_EVAL_EPISODES"]),
                            seed=int(TEST_SETTINGS["LEAGUE_EVAL_SEED"]))
        assert entered[submission_id]["evaluation"]["mean_return"] == pytest.approx(local.mean_return, abs=1e-9)
    assert sorted((j["kind"], j["submission_id"]) for j in entry_jobs) == \
        sorted((kind, i) for i in files for kind in ("validate", "evaluate"))
    assert all((j["status"], j["attempts"], j["error"]) == ("done", 1, None) for j in entry_jobs), entry_jobs
    assert {worker_pid(j) for j in entry_jobs} == set(pids), "both hosts took uploads"
    sha = {i: s["sha256"] for i, s in entered.items()}
    for k, pid in enumerate(pids):
        data = tmp_path / f"host-{k}" / "data"
        fetched = {i for i in files if (data / "blobs" / sha[i][:2] / sha[i]).exists()}
        assert fetched >= {j["submission_id"] for j in entry_jobs if worker_pid(j) == pid}
        assert all((data / "blobs" / sha[i][:2] / sha[i]).read_bytes() == files[i].read_bytes() for i in fetched)
        assert not (data / "league.db").exists()

    # the round: the cut host's heat raced again, from the start, by the other host; counted once
    by_race = {j["race_id"]: j for j in jobs}
    again = by_race[cut_job["race_id"]]
    assert again["attempts"] == 2 and worker_pid(again) == pids[1], again
    assert "stopped heart-beating" in again["error"] and f"/{pids[0]}/" in again["error"], again["error"]
    assert all((j["attempts"], j["error"]) == (1, None) for j in jobs if j is not again), jobs
    heat = races[cut_job["race_id"]]
    local = race([load_agent(files[e["submission_id"]]) for e in heat["entrants"]], seed=finished["track_seed"],
                 names=[f"{e['name']} ({e['owner']})" for e in heat["entrants"]], **LONG_HEATS)
    assert [(r["position"], r["car"], r["outcome"]) for r in heat["classification"]] == \
        [(r["position"], r["car"], r["outcome"]) for r in local.classification]
    assert [r["time"] for r in heat["classification"]] == pytest.approx([r["time"] for r in local.classification])

    # the cut host's heartbeat hung on the cut link, and by then the lease was the other host's. What it
    # saw next depends on the machine's speed: at its next heartbeat, the lease lost (it stopped its heat);
    # or, its heat raced to the end first, its result refused at completion; or its connections still
    # failing (heartbeat failed, its completion an error) until it stopped. Whichever: it changed nothing
    # (below), and it did race its heat and find its lease in doubt
    assert re.search(rf"job {cut_job['id']}: (lease lost|heartbeat failed)", log_of_cut_host), log_of_cut_host[-3000:]
    assert after["round"] == finished and after["standings"] == table
    assert [j for j in after["jobs"] if j["status"] not in ("done",)] == []
    assert sorted(j["id"] for j in after["jobs"]) == sorted(j["id"] for j in entry_jobs + jobs)
    assert {j["id"]: (j["attempts"], j["worker_id"]) for j in after["jobs"] if j["kind"] == "race"} == \
        {j["id"]: (j["attempts"], j["worker_id"]) for j in jobs}
    assert alive == [True] * HOSTS

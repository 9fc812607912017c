"""What a model process could do if it took control of its runtime: every attempt refused.

A sandbox confines itself (league.server.sandbox.child.confine: limits, network namespace, its own
user, Landlock, seccomp) before it reads the model. Here a process is confined by that same
function, as the fork server's children are, and then tries what a hostile model would: read the
league's database, another student's model, /etc/shadow; connect to PostgreSQL and Redis; run a
program; write outside its directory; fork; signal its parent. Run as root by the suite, and as an
unprivileged user by test_unprivileged.py.
"""
from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from league.server.sandbox import child
from league.server.sandbox.limits import SandboxLimits
from league.server.sandbox.process import _child_environment, isolation

ATTACKS = r'''
import json, os, signal, socket, sys
results = {}

def attempt(name, action):
    try:
        action()
        results[name] = "done"
    except OSError as error:
        results[name] = f"refused ({error.strerror})"

sys.path.insert(0, os.environ["LEAGUE_PARENT"])
from league.server.sandbox import child
results["isolation"] = child.confine(600, int(sys.argv[1]), os.getppid())
data = sys.argv[2]
attempt("read the database", lambda: open(f"{data}/league.db", "rb").read())
attempt("read another student's model", lambda: open(f"{data}/blobs/ab/abcdef", "rb").read())
attempt("read /etc/shadow", lambda: open("/etc/shadow", "rb").read())
attempt("list the data directory", lambda: os.listdir(data))
attempt("connect to PostgreSQL", lambda: socket.create_connection(("127.0.0.1", 5432), timeout=2))
attempt("connect to Redis", lambda: socket.create_connection(("127.0.0.1", 6379), timeout=2))
attempt("open a unix socket", lambda: socket.socket(socket.AF_UNIX))
attempt("run a program", lambda: os.execv("/bin/sh", ["sh", "-c", "true"]))
attempt("write in /tmp", lambda: open("/tmp/league-sandbox-escape", "w").write("x"))
attempt("write in /dev/shm", lambda: open("/dev/shm/league-sandbox-escape", "w").write("x"))
attempt("fork", lambda: os.fork() or os._exit(0))
attempt("signal its parent", lambda: os.kill(os.getppid(), signal.SIGCONT))
attempt("write in its own directory", lambda: open("scratch", "w").write("x"))
print(json.dumps(results))
'''
REFUSED = ["read the database", "read another student's model", "read /etc/shadow", "list the data directory",
           "connect to PostgreSQL", "connect to Redis", "open a unix socket", "run a program", "write in /tmp",
           "write in /dev/shm", "fork", "signal its parent"]


@pytest.fixture
def data_dir(tmp_path) -> Path:
    """A league's data directory as the server leaves it: the database, and a student's model."""
    data = tmp_path / "data"
    (data / "blobs" / "ab").mkdir(parents=True)
    sqlite3.connect(data / "league.db").execute("CREATE TABLE users (token_hash TEXT)").connection.commit()
    (data / "blobs" / "ab" / "abcdef").write_bytes(b"another student's model")
    for path in (data / "league.db", data / "blobs" / "ab" / "abcdef"):
        os.chmod(path, 0o600)
    return data


def test_a_model_that_took_over_its_process_is_refused_everything(data_dir, tmp_path):
    uid_base = isolation(SandboxLimits()).uid_base  # what this machine's sandboxes run with
    workdir = tmp_path / "sandbox"
    workdir.mkdir(mode=0o700)
    env = {**_child_environment(workdir), "LEAGUE_PARENT": str(Path(child.__file__).resolve().parents[3])}
    result = subprocess.run([sys.executable, "-s", "-B", "-c", ATTACKS, str(uid_base), str(data_dir)], cwd=workdir,
                            env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    outcome = json.loads(result.stdout)
    assert outcome.pop("write in its own directory") == "done"
    assert {name: outcome[name].split(" ")[0] for name in REFUSED} == {name: "refused" for name in REFUSED}, outcome
    assert outcome["isolation"]["landlock"] > 0 and outcome["isolation"]["seccomp"]
    assert outcome["isolation"]["network"] in ("namespace", "user-namespace")  # no network even without seccomp
    assert not Path("/tmp/league-sandbox-escape").exists() and not Path("/dev/shm/league-sandbox-escape").exists()


def test_the_data_directory_and_the_database_are_private(tmp_path):
    """The store and the database files are the server's alone (0700 / 0600), whoever else is on the machine."""
    from league.server.db.session import make_engine, migrate
    from league.server.storage import BlobStore

    store = BlobStore(tmp_path / "data")
    store.ensure()
    engine = make_engine(f"sqlite:///{tmp_path / 'data' / 'league.db'}")
    migrate(engine)
    with engine.begin() as connection:  # a write: the WAL and its index exist now
        connection.exec_driver_sql("UPDATE courses SET name = name")
    engine.dispose()
    modes = {path.name: path.stat().st_mode & 0o777 for path in (tmp_path / "data").iterdir()}
    assert modes["blobs"] == modes["tmp"] == 0o700
    assert {name: mode for name, mode in modes.items() if name.startswith("league.db")} == \
        {name: 0o600 for name in modes if name.startswith("league.db")}
    assert (tmp_path / "data").stat().st_mode & 0o077 == 0

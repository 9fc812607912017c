"""What a model process could do if it took control of its runtime: every attempt refused.

A sandbox confines itself (league.server.sandbox.child.confine: limits, network namespace, its own
user, Landlock, seccomp) before it reads the model. Here the real fork server (child.py, started as
ForkServer starts it) forks sandboxes as it does for models, and each runs Python code in place of
loading a model, once confined: what a hostile model would do if it took over its runtime. It tries
to read the league's database, another student's model, /etc/shadow; to connect to PostgreSQL and
Redis; to run a program; to write outside its directory; to fork; to signal its parent; and to act
on other processes (their limits, priorities, CPUs, memory) and on IPC objects. Run as root by the
suite, and as an unprivileged user by tests/system/test_unprivileged_sandbox.py.
"""
from __future__ import annotations

import json
import os
import sqlite3
import sys
import tempfile
from pathlib import Path

import pytest

from league.server.sandbox import child, process
from league.server.sandbox.process import ForkServer, _child_environment
from league.validation.limits import SandboxLimits

# child.py run as the fork server, except that its sandboxes run a model file named *.py as Python
# instead of loading it (after confine(), as they would load it)
HIJACKED_FORK_SERVER = '''
import runpy, sys
main = runpy.run_path({child!r}, run_name="league_sandbox_child")["main"]
load_model = main.__globals__["load_model"]

def run_model_as_python(model_path, memory_mb):
    if model_path.suffix != ".py":
        return load_model(model_path, memory_mb)
    exec(compile(open(model_path).read(), str(model_path), "exec"), {{"__name__": "__hijacked__"}})

main.__globals__["load_model"] = run_model_as_python
sys.exit(main(["child.py", *sys.argv[1:]]))
'''

FILES_AND_NETWORK = r'''
import json, os, signal, socket
results = {}

def attempt(name, action):
    try:
        action()
        results[name] = "done"
    except OSError as error:
        results[name] = f"refused ({error.strerror})"

data = os.environ["DATA"]
attempt("read the database", lambda: open(f"{data}/league.db", "rb").read())
attempt("read another student's model", lambda: open(f"{data}/blobs/ab/abcdef", "rb").read())
attempt("read /etc/shadow", lambda: open("/etc/shadow", "rb").read())
attempt("list the data directory", lambda: os.listdir(data))
attempt("connect to PostgreSQL", lambda: socket.socket(socket.AF_INET).connect(("127.0.0.1", 5432)))
attempt("connect to Redis", lambda: socket.socket(socket.AF_INET).connect(("127.0.0.1", 6379)))
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

# Each call sets what its target already has (its limit, nice value, CPUs, policy, I/O priority;
# pages from node 0 to node 0): where it is not refused, it changes nothing.
PROCESSES = r'''
import ctypes, errno, json, os, resource
import pyseccomp

libc = ctypes.CDLL(None, use_errno=True)
NOFILE, WHO_PROCESS, WHO_PGRP = resource.RLIMIT_NOFILE, 1, 2

def syscall(name, *args):
    number = pyseccomp.resolve_syscall(pyseccomp.Arch.NATIVE, name)
    result = libc.syscall(ctypes.c_long(number), *(ctypes.c_long(a) if isinstance(a, int) else a for a in args))
    if result < 0:
        raise OSError(ctypes.get_errno(), name)
    return result

def sched_setattr(pid):
    attr = ctypes.create_string_buffer(56)
    syscall("sched_getattr", pid, attr, 56, 0)
    syscall("sched_setattr", pid, attr, 0)

def ioprio_set(which, who):
    syscall("ioprio_set", which, who, syscall("ioprio_get", which, who))

NODE_0, HEAD, LENGTH = ctypes.byref(ctypes.c_ulong(1)), ctypes.byref(ctypes.c_void_p()), ctypes.byref(ctypes.c_size_t())
ON_A_PROCESS = {
    "prlimit": lambda pid: resource.prlimit(pid, NOFILE, resource.prlimit(pid, NOFILE)),
    "setpriority": lambda pid: os.setpriority(os.PRIO_PROCESS, pid, os.getpriority(os.PRIO_PROCESS, pid)),
    "sched_setaffinity": lambda pid: os.sched_setaffinity(pid, os.sched_getaffinity(pid)),
    "sched_setscheduler": lambda pid: os.sched_setscheduler(pid, os.sched_getscheduler(pid), os.sched_getparam(pid)),
    "sched_setparam": lambda pid: os.sched_setparam(pid, os.sched_getparam(pid)),
    "sched_setattr": sched_setattr,
    "ioprio_set": lambda pid: ioprio_set(WHO_PROCESS, pid),
    "migrate_pages": lambda pid: syscall("migrate_pages", pid, 64, NODE_0, NODE_0),
    "move_pages": lambda pid: syscall("move_pages", pid, 0, None, None, None, 0),
    "get_robust_list": lambda pid: syscall("get_robust_list", pid, HEAD, LENGTH),
    "kcmp": lambda pid: syscall("kcmp", os.getpid(), pid, 1, 0, 0),  # KCMP_VM
    "process_vm_readv": lambda pid: syscall("process_vm_readv", pid, None, 0, None, 0, 0),
    "pidfd_open": lambda pid: os.close(os.pidfd_open(pid)),
    "kill": lambda pid: os.kill(pid, 0),
}
SELF_ONLY = [name for name in ON_A_PROCESS if name not in ("kcmp", "process_vm_readv", "pidfd_open", "kill")]

def checked(result):
    if result < 0:
        raise OSError(ctypes.get_errno(), "refused")
    return result

def shared_memory():
    libc.shmctl(checked(libc.shmget(0, 4096, 0o600)), 0, None)  # IPC_PRIVATE, then IPC_RMID

def message_queue():
    os.close(checked(libc.mq_open(b"/league-sandbox-probe", os.O_RDWR | os.O_CREAT, 0o600, None)))
    libc.mq_unlink(b"/league-sandbox-probe")

BEYOND_ITSELF = {
    "setpriority of its process group": lambda: os.setpriority(os.PRIO_PGRP, 0, os.getpriority(os.PRIO_PGRP, 0)),
    "setpriority of its user": lambda: os.setpriority(os.PRIO_USER, 0, os.getpriority(os.PRIO_USER, 0)),
    "ioprio_set of its process group": lambda: ioprio_set(WHO_PGRP, 0),
    "a session of its own": os.setsid,
    "a process group of its own": lambda: os.setpgid(0, 0),
    "SysV shared memory": shared_memory,
    "a POSIX message queue": message_queue,
}

def outcome(action, *args):
    try:
        action(*args)
        return "done"
    except OSError as error:
        return errno.errorcode.get(error.errno, str(error.errno))

others = {"its fork server": os.getppid(), "the test process": int(os.environ["TEST_PID"])}
print(json.dumps({
    "others": {who: {name: outcome(call, pid) for name, call in ON_A_PROCESS.items()} for who, pid in others.items()},
    "itself": {who: {name: outcome(ON_A_PROCESS[name], pid) for name in SELF_ONLY}
               for who, pid in {"as 0": 0, "by its pid": os.getpid()}.items()},
    "beyond itself": {name: outcome(call) for name, call in BEYOND_ITSELF.items()},
}))
'''


@pytest.fixture(scope="module")
def hijacked(tmp_path_factory):
    """run(code, **env) -> (the sandbox's isolation report, the JSON its code printed): a sandbox of
    the real fork server, started as a model's is (this machine's uid_base), that runs `code`."""
    uid_base = process.sandbox_isolation().uid_base  # what this machine's sandboxes run with
    wrapper = tmp_path_factory.mktemp("hijacked") / "fork_server.py"
    wrapper.write_text(HIJACKED_FORK_SERVER.format(child=str(Path(child.__file__).resolve())))
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(process, "CHILD_SCRIPT", wrapper)
        server = ForkServer(".onnx")

    def run(code: str, **env: str) -> tuple[dict, dict]:
        workdir = Path(tempfile.mkdtemp(prefix="league-sandbox-"))
        (workdir / "model.py").write_text(code)
        os.chmod(workdir / "model.py", 0o644)  # readable by the sandbox's own user, as a model is
        sandbox = server.spawn(["model.py", "0", "600", str(uid_base)], workdir, {**_child_environment(workdir), **env})
        with sandbox.stdin, sandbox.stdout, sandbox.stderr:
            tag, message, printed = sandbox.stdout.read(1), sandbox.stdout.read(), sandbox.stderr.read().decode()
        sandbox.wait()
        assert tag == b"R", (message, printed)
        return json.loads(message[4:])["isolation"], json.loads(printed.strip().splitlines()[-1])

    try:
        yield run
    finally:
        server.close()


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


def test_a_model_that_took_over_its_process_is_refused_everything(hijacked, data_dir):
    report, outcome = hijacked(FILES_AND_NETWORK, DATA=str(data_dir))
    assert outcome.pop("write in its own directory") == "done"
    assert {name: outcome[name].split(" ")[0] for name in REFUSED} == {name: "refused" for name in REFUSED}, outcome
    assert report["landlock"] > 0 and report["seccomp"]
    assert report["network"] in ("namespace", "user-namespace")  # no network even without seccomp
    assert not Path("/tmp/league-sandbox-escape").exists() and not Path("/dev/shm/league-sandbox-escape").exists()


def test_a_model_that_took_over_its_process_acts_on_no_other_process(hijacked):
    """Limits, priorities, CPUs, scheduling, memory of its fork server and of the server itself
    (here the test), of its process group or its user; IPC objects; a session of its own (a
    scheduling group of its own): all refused. On itself, named 0, the same calls work; named by
    its pid they are refused (the rules are the same in every sandbox, built once per fork server)."""
    report, outcome = hijacked(PROCESSES, TEST_PID=str(os.getpid()))
    refused = {who: {name: "EPERM" for name in calls} for who, calls in outcome["others"].items()}
    assert outcome["others"] == refused
    assert outcome["beyond itself"] == {name: "EPERM" for name in outcome["beyond itself"]}
    calls = sorted(outcome["itself"]["as 0"])
    assert len(calls) == 10 and sorted(outcome["itself"]["by its pid"]) == calls
    assert outcome["itself"] == {"as 0": dict.fromkeys(calls, "done"), "by its pid": dict.fromkeys(calls, "EPERM")}
    assert report["user"].startswith("uid ") if os.geteuid() == 0 else report["user"] == "the server's user"


def test_a_root_servers_sandboxes_get_a_user_id_of_their_own_even_from_a_private_python():
    """This machine's Python (a pyenv under /root, mode 700) is private to root: sandboxes run as a
    user id of their own anyway, with their runtimes loaded before the change; the probe loaded and
    ran a tiny model of each runtime so confined. As an ordinary user, they run as that user."""
    found = process.sandbox_isolation()
    assert found.full and found.missing == [], found.describe()
    assert found.runtimes == ("onnx", "torchscript")  # each loaded and ran, confined
    if os.geteuid() != 0:
        assert (found.user, found.runtime) == ("the server's user", "readable")
        return
    assert found.user.startswith("uid ") and int(found.user.split()[1]) > SandboxLimits.uid_base
    private = any(not os.stat(parent).st_mode & 0o001 for parent in Path(sys.base_prefix).parents)
    assert found.runtime == ("preloaded" if private else "readable")


def test_a_root_server_whose_sandboxes_keep_roots_user_id_says_so_and_what_to_do():
    """Partial isolation says what is missing: as root with LEAGUE_SANDBOX_UID_BASE=0, and as root
    when a sandbox cannot take its user id (here one past the largest there is)."""
    if os.geteuid() != 0:
        assert process.sandbox_isolation(0).full  # an ordinary user's sandboxes run as that user anyway
        return
    unset = process.sandbox_isolation(0)
    assert (unset.full, unset.user, unset.uid_base) == (False, "root without capabilities", 0)
    assert unset.missing == ["a user id of its own: LEAGUE_SANDBOX_UID_BASE is 0, so sandboxes run as root without "
                             "capabilities, which still owns root's files and processes: unset it (each sandbox "
                             "then runs as 1342177280 + its pid)"]
    assert unset.to_dict()["missing"] == unset.missing and not unset.to_dict()["full"]
    failing = process._probe_isolation(2**32 - 1)  # uid_base + pid: no such user id
    assert (failing.full, failing.user, failing.uid_base) == (False, "root without capabilities", 0)
    assert failing.missing[0].startswith("a user id of its own: with one, the probe sandbox failed (")
    assert failing.missing[0].endswith("so sandboxes run as root without capabilities, which still owns root's "
                                       "files and processes: run the server as an ordinary user, or from a Python "
                                       "every user may read (league/server/README.md, \"Sandbox users\")")
    assert "NOT fully isolated, missing a user id of its own" in failing.describe()


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

"""The sandbox process seen from the worker: starting it (a fork server per thread), who it runs
as, its environment and directory, and the pipe protocol of league/server/sandbox/child.py.

Each thread that starts sandboxes has a `ForkServer` per runtime, a child.py process that has
loaded and run a tiny model of that runtime once and forks a sandbox per model (one start is a fork
and a model load, ~0.015 s for ONNX, instead of a new interpreter, ~0.25 s, and torch's import,
~2.5 s). A worker's job threads start theirs when they start (ForkServer.prepare_this_thread). A
server dies with its thread and takes its sandboxes with it (the kernel's parent-death signal,
which follows the starting thread).
Sandboxes run on the CPUs their thread may use when they start (see league.server.jobs.placement).
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from league.agents import plain_text
from league.server.sandbox import child
from league.server.sandbox.log import LogBuffer
from league.validation.limits import SandboxLimits
from league.validation.timing import load_over

log = logging.getLogger("league.server.sandbox")
CHILD_SCRIPT = Path(child.__file__).resolve()
HEADER, LENGTH = child.HEADER, child.LENGTH
MAX_MESSAGE = 65536
# A model's failure on a batch, as the child says it, is made plain text again (the child may lie)
# and kept whole up to this length: the toolkit's own reason, as `league evaluate` gives it ("the
# model raised TYPE: " and 300 characters). (A load's failure is cut at 300, as `league check`'s.)
REASON_CHARS = 1000
# The child's answers are read into one buffer that holds the largest frame twice over: an action
# frame of MAX_BATCH rows (9 + 8 * 4096 bytes) or a text message of MAX_MESSAGE bytes (5 + 65536)
ANSWER_BUFFER = 2 * (LENGTH.size + 1 + MAX_MESSAGE)
SEND_BUFFER = 16384  # an observation frame of 128 lidar rows; grown for a larger batch
FRAME_AT = 3  # a frame is written from here, so that its floats (after 9 bytes of header) are aligned
FORK_SERVER_TIMEOUT_S = 300.0  # its imports and tiny models on a busy machine (torch's took 35 s on one)
# Wall-clock backstops of a CPU-time budget: only a child that stops using the CPU without
# answering reaches them; a busy machine stretches a call's wall time far less than 30x.
WALL_BACKSTOP, WALL_MARGIN_S = 30.0, 5.0  # a call: 30x its CPU budget, + 5 s
LOAD_WALL_BACKSTOP = 4.0  # a load: 4x its CPU budget


class SandboxFailure(Exception):
    """The child failed; `fatal` when it is dead or was killed (a new one is needed)."""

    def __init__(self, reason: str, fatal: bool, timed_out: bool = False):
        super().__init__(reason)
        self.reason, self.fatal, self.timed_out = reason, fatal, timed_out



def cpu_clock_of(pid: int) -> int:
    """The clock id of a process's CPU time (Linux's MAKE_PROCESS_CPUCLOCK(pid, CPUCLOCK_SCHED)):
    readable for any process we can see, whatever its user."""
    return (~pid << 3) | 2


class Budget:
    """What one answer of the child may take: `cpu_s` of the child's own CPU time, so that a busy
    machine (which delays the child but does not make it use more CPU) changes nothing; and a
    wall-clock backstop, `wall_s`, for a child that stops using the CPU without answering.
    (A plain class with slots: one is made per call, hundreds per evaluation.)"""

    __slots__ = ("clock", "cpu_s", "wall_s", "cpu_start", "wall_end")

    def __init__(self, clock: Callable[[], float], cpu_s: float, wall_s: float):
        self.clock, self.cpu_s, self.wall_s = clock, cpu_s, wall_s  # clock: the child's CPU time
        self.cpu_start, self.wall_end = clock(), time.monotonic() + wall_s

    def __repr__(self) -> str:
        return f"Budget(cpu_s={self.cpu_s!r}, wall_s={self.wall_s!r})"

    @classmethod
    def for_call(cls, clock: Callable[[], float], cpu_s: float) -> Budget:
        return cls(clock, cpu_s, WALL_BACKSTOP * cpu_s + WALL_MARGIN_S)

    def used(self) -> float:
        return self.clock() - self.cpu_start

    def wait_s(self) -> float:
        """How long to wait before looking again (the child cannot use more CPU than time passes,
        being one thread); 0 once the budget is spent."""
        left = min(self.cpu_s - self.used(), self.wall_end - time.monotonic())
        return 0.0 if left <= 0 else max(left, 0.001)

    def spent_on_the_wall_clock(self) -> bool:
        return time.monotonic() >= self.wall_end and self.used() < self.cpu_s


class SandboxProcess:
    """One child process serving one model."""

    def __init__(self, model_file: Path, model_kind: str, limits: SandboxLimits, log: LogBuffer):
        self.limits, self.log = limits, log
        uid_base = isolation(limits).uid_base  # before the directory: a refusal leaves nothing behind
        self.workdir = Path(tempfile.mkdtemp(prefix="league-sandbox-"))
        try:
            runtime = ".onnx" if model_kind == "onnx" else ".pt"
            model_name = f"model{runtime}"
            shutil.copyfile(model_file, self.workdir / model_name)
            os.chmod(self.workdir / model_name, 0o644)  # readable by the sandbox's own user
            args = [model_name, str(limits.memory_mb), str(limits.cpu_seconds), str(uid_base)]
            self.proc = ForkServer.of_this_thread(runtime).spawn(args, self.workdir, _child_environment(self.workdir))
        except BaseException:
            shutil.rmtree(self.workdir, ignore_errors=True)
            raise
        self._cpu_clock, self._cpu_time = cpu_clock_of(self.proc.pid), 0.0
        self._in = self.proc.stdin.fileno()  # written with os.write, never through the file's buffer
        self._answers = AnswerReader(self.proc.stdout.fileno(), self._death_reason, self.kill)
        self._send_buffer(SEND_BUFFER)
        self._log_thread = threading.Thread(target=self._copy_log, daemon=True)
        self._log_thread.start()
        try:
            self.ready = self._await_ready()
        except BaseException:
            self.close()  # the process, the pipes and the directory: nothing of a failed start is left
            raise

    def _copy_log(self) -> None:
        for chunk in iter(lambda: self.proc.stderr.read1(65536), b""):
            self.log.write(chunk)

    def cpu_time(self) -> float:
        """The child's CPU time so far, in seconds (its last reading once it is gone)."""
        if self._cpu_clock is not None:  # not once it is reaped: its pid may be another process's
            try:
                self._cpu_time = time.clock_gettime(self._cpu_clock)
            except OSError:
                pass
        return self._cpu_time

    def _await_ready(self) -> dict:
        limit = self.limits.load_cpu_s
        try:
            tag, payload = self._answers.message(Budget(self.cpu_time, limit, LOAD_WALL_BACKSTOP * limit),
                                                 expected=(b"R", b"E"))
        except SandboxFailure as failure:
            if failure.timed_out:
                raise SandboxFailure(load_over(self.limits), fatal=True) from failure
            raise
        if tag == b"E":
            raise SandboxFailure(plain_text(payload.decode("utf-8", errors="replace")), fatal=True)
        return json.loads(payload)

    def _send_buffer(self, size: int) -> None:
        self._frame = bytearray(size)
        self._frame_view = memoryview(self._frame)
        self._frame_floats = np.frombuffer(self._frame, dtype="<f4", offset=FRAME_AT + HEADER.size)

    def send_observations(self, obs: np.ndarray) -> None:
        """One write of the frame b"I" n d + n*d float32, built in a buffer kept for the process."""
        n, d = obs.shape
        end = FRAME_AT + HEADER.size + 4 * n * d
        if end > len(self._frame):
            self._send_buffer(end)
        HEADER.pack_into(self._frame, FRAME_AT, b"I", n, d)
        self._frame_floats[:n * d] = obs.reshape(-1)  # (cast to float32 as np.ascontiguousarray did)
        self._write(self._frame_view[FRAME_AT:end])

    def receive_actions(self, budget: Budget) -> np.ndarray:
        return self._answers.actions(budget)

    def _write(self, data: memoryview) -> None:
        try:
            while data:
                data = data[os.write(self._in, data):]
        except OSError as error:  # BrokenPipeError: the child is gone
            raise SandboxFailure(self._death_reason(), fatal=True) from error

    def _death_reason(self) -> str:
        try:
            code = self.proc.wait(timeout=2)
        except subprocess.TimeoutExpired:
            self.kill()
            return "the sandbox stopped answering"
        if code == -signal.SIGXCPU:
            return f"the model used more than {self.limits.cpu_seconds} s of CPU time"
        if code < 0:
            return f"the sandbox process crashed ({signal.Signals(-code).name}); see the log"
        return f"the sandbox process exited with code {code}; see the log"

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self.cpu_time()  # its last reading: a killed child's clock stands until it is reaped
        self._cpu_clock = None

    def close(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            self.proc.stdin.close()
        self.kill()  # nothing in the child is worth its slow interpreter shutdown
        self._log_thread.join(timeout=2)
        self.proc.stdout.close()
        self.proc.stderr.close()
        shutil.rmtree(self.workdir, ignore_errors=True)


class AnswerReader:
    """The child's answers (league.server.sandbox.child's protocol), read from its stdout within a
    call's budget into one preallocated buffer: no allocation per read, and one poll and one read
    for an answer that comes in one piece. Anything that is not a well-formed frame (an unknown
    tag, actions of another width or more rows than a request may hold, a text longer than
    MAX_MESSAGE) kills the child and is a fatal SandboxFailure; so is the end of its output (its
    death) or an answer that does not come within the budget. Bytes after a frame are kept for the
    next one (a child that sends more than it was asked for fails there)."""

    def __init__(self, fd: int, death_reason: Callable[[], str], kill: Callable[[], None]):
        self.fd, self._death_reason, self._kill = fd, death_reason, kill
        os.set_blocking(fd, False)
        self._poller = select.poll()
        self._poller.register(fd, select.POLLIN)
        self._buffer = bytearray(ANSWER_BUFFER)
        self._view = memoryview(self._buffer)
        self._start = self._end = 0  # the unread bytes: self._buffer[self._start:self._end]

    def actions(self, budget: Budget) -> np.ndarray:
        """The next answer to an observation batch: float32 (n, 2) actions (a copy, the caller's),
        or SandboxFailure: the model's failure (an E message: not fatal) or the child's."""
        if self._start == self._end:  # nothing read yet: the child needs the CPU first, wait for it
            self._poller.poll(1000 * min(budget.cpu_s, budget.wall_s))  # (the child is one thread)
        tag, payload = self.message(budget, expected=(b"A", b"E"))
        if tag == b"E":
            raise SandboxFailure(plain_text(payload.decode("utf-8", errors="replace"), REASON_CHARS), fatal=False)
        return payload

    def message(self, budget: Budget, expected: tuple[bytes, ...]) -> tuple[bytes, object]:
        """(tag, payload): actions for b"A", the message's bytes for the others."""
        self._fill(1, budget)
        tag = self._buffer[self._start:self._start + 1]
        if tag not in expected:
            raise self._protocol_error(f"message {bytes(tag)!r}")
        if tag == b"A":
            self._fill(HEADER.size, budget)
            _, n, d = HEADER.unpack_from(self._buffer, self._start)
            if d != 2 or n > child.MAX_BATCH:
                raise self._protocol_error(f"actions {n}x{d}")
            size = HEADER.size + 8 * n
            self._fill(size, budget)  # (which may move the unread bytes to the buffer's front)
            actions = np.frombuffer(self._buffer, dtype="<f4", count=2 * n, offset=self._start + HEADER.size)
            self._consume(size)
            return b"A", actions.reshape(n, 2).copy()
        self._fill(1 + LENGTH.size, budget)
        (length,) = LENGTH.unpack_from(self._buffer, self._start + 1)
        if length > MAX_MESSAGE:
            raise self._protocol_error("message too long")
        size = 1 + LENGTH.size + length
        self._fill(size, budget)
        payload = bytes(self._view[self._start + 1 + LENGTH.size:self._start + size])
        self._consume(size)
        return bytes(tag), payload

    def _protocol_error(self, what: str) -> SandboxFailure:
        self._kill()
        return SandboxFailure(f"sandbox protocol error ({what})", fatal=True)

    def _consume(self, size: int) -> None:
        self._start += size
        if self._start == self._end:
            self._start = self._end = 0

    def _fill(self, size: int, budget: Budget) -> None:
        """At least `size` unread bytes (size <= half the buffer), within the budget."""
        if self._end - self._start >= size:
            return
        if self._start + size > len(self._buffer):  # the frame would not fit after what was read
            unread = self._end - self._start
            self._buffer[:unread] = self._view[self._start:self._end]
            self._start, self._end = 0, unread
        while self._end - self._start < size:
            try:
                got = os.readv(self.fd, [self._view[self._end:]])
            except BlockingIOError:
                wait_s = budget.wait_s()
                if wait_s <= 0:
                    self._kill()
                    raise SandboxFailure("out of time", fatal=True, timed_out=True) from None
                self._poller.poll(wait_s * 1000)
                continue
            if not got:
                raise SandboxFailure(self._death_reason(), fatal=True)
            self._end += got


class ForkServer:
    """child.py's fork server for one runtime (its models' suffix): one per thread that starts
    sandboxes and runtime, since the kernel's parent-death signal follows the thread that started a
    process; it ends with that thread."""

    _threads = threading.local()

    @classmethod
    def of_this_thread(cls, runtime: str) -> ForkServer:
        servers = cls._servers()
        server = servers.get(runtime)
        if server is None or server.proc.poll() is not None:
            server = servers[runtime] = cls(runtime, prepare_when_idle=getattr(cls._threads, "prepare", False))
        return server

    @classmethod
    def _servers(cls) -> dict[str, ForkServer]:
        if not hasattr(cls._threads, "servers"):
            cls._threads.servers = {}
        return cls._threads.servers

    @classmethod
    def prepare_this_thread(cls) -> None:
        """Start this thread's servers now, one per installed runtime, and have the TorchScript one
        (and any that replaces it) prepare torch while no sandbox is asked for: a worker's job thread,
        so that its first TorchScript model waits for no import of torch. Costs each job thread
        torch's memory from the start."""
        cls._threads.prepare = True
        for runtime in installed_runtimes():
            cls.of_this_thread(runtime)

    @classmethod
    def release_this_thread(cls) -> None:
        """End this thread's servers: the thread starts no more sandboxes (it only probed isolation)."""
        servers = cls._servers()
        while servers:
            servers.popitem()[1].close()

    def __init__(self, runtime: str, prepare_when_idle: bool = False):
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        home = Path(tempfile.gettempdir())
        with theirs:
            self.proc = subprocess.Popen(
                [sys.executable, "-s", "-B", "-P", str(CHILD_SCRIPT), "--fork-server", str(theirs.fileno()), runtime,
                 *(["--prepare-when-idle"] if prepare_when_idle else [])],
                cwd="/", env=_child_environment(home), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                pass_fds=[theirs.fileno()], start_new_session=True)
        self.control = ours
        self.control.settimeout(FORK_SERVER_TIMEOUT_S)
        self.cpus = os.sched_getaffinity(0)  # the thread's, inherited by the server
        self._lock = threading.Lock()

    def spawn(self, args: list[str], workdir: Path, env: dict[str, str]) -> ForkedProcess:
        """A sandbox process running child.py `args` in `workdir`, with pipes to its stdio,
        on the CPUs the calling thread may use now (league.server.jobs.placement moves job threads)."""
        self._follow_thread_affinity()
        (stdin, to_stdin), (from_stdout, stdout), (from_stderr, stderr) = (os.pipe() for _ in range(3))
        ours = [to_stdin, from_stdout, from_stderr]
        try:
            reply = self._ask({"args": args, "workdir": str(workdir), "env": env}, [stdin, stdout, stderr])
        except BaseException:
            for fd in ours:
                os.close(fd)
            raise
        finally:  # the child has its copies (or there is no child)
            for fd in (stdin, stdout, stderr):
                os.close(fd)
        return ForkedProcess(reply["pid"], self, stdin=open(to_stdin, "wb"),
                             stdout=open(from_stdout, "rb", buffering=0), stderr=open(from_stderr, "rb"))

    def _follow_thread_affinity(self) -> None:
        cpus = os.sched_getaffinity(0)
        if cpus != self.cpus:
            with contextlib.suppress(ProcessLookupError):  # (a dead server fails the request next)
                os.sched_setaffinity(self.proc.pid, cpus)  # the server has one thread
            self.cpus = cpus

    def close(self) -> None:
        """End the server (it exits when its control socket closes; its sandboxes die with it)."""
        self.control.close()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def exit_status(self, pid: int) -> int | None:
        try:
            return self._ask({"wait": pid})["status"]
        except SandboxFailure:
            return -signal.SIGKILL  # the server is gone, and its children with it

    def _ask(self, request: dict, fds: list[int] = ()) -> dict:
        with self._lock:
            try:
                socket.send_fds(self.control, [json.dumps(request).encode()], list(fds))
                reply = self.control.recv(65536)
            except OSError as error:  # timeouts included
                self.proc.kill()
                raise SandboxFailure(f"the sandbox launcher failed: {error}", fatal=True) from error
        if not reply:
            raise SandboxFailure("the sandbox launcher exited", fatal=True)
        return json.loads(reply)


class ForkedProcess:
    """What SandboxProcess needs of a Popen, for a child of the fork server (a pidfd to signal it
    and to see it end; its exit status from the server)."""

    def __init__(self, pid: int, server: ForkServer, *, stdin, stdout, stderr):
        self.pid, self.server = pid, server
        self.stdin, self.stdout, self.stderr = stdin, stdout, stderr
        self.returncode: int | None = None
        self._pidfd = os.pidfd_open(pid)  # safe: the server keeps the pid until asked for its status

    def poll(self) -> int | None:
        return self.wait(timeout=0) if self.returncode is None and self._ended(0) else self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None:
            if not self._ended(timeout):
                raise subprocess.TimeoutExpired(f"sandbox {self.pid}", timeout)
            self.returncode = self.server.exit_status(self.pid)
            if self.returncode is None:  # ended as the pidfd says, not yet as the server sees it
                self.returncode = -signal.SIGKILL
            os.close(self._pidfd)
        return self.returncode

    def kill(self) -> None:
        if self.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                signal.pidfd_send_signal(self._pidfd, signal.SIGKILL)

    def _ended(self, timeout: float | None) -> bool:
        return bool(select.select([self._pidfd], [], [], timeout)[0])


def _child_environment(workdir: Path) -> dict[str, str]:
    """No proxies, no credentials, no PYTHONPATH of ours: only what Python and one-thread math need."""
    return {"PATH": os.defpath, "HOME": str(workdir), "TMPDIR": str(workdir), "LANG": "C.UTF-8",
            "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MALLOC_ARENA_MAX": "2",
            "ORT_DISABLE_TELEMETRY": "1"}


# --------------------------------------------------------------------------- isolation


class IsolationUnavailable(RuntimeError):
    """Sandboxes cannot be isolated here as the settings require: a fault of the machine, not of a
    model (the job fails with this reason; nothing is held against the upload)."""


@dataclass(frozen=True)
class Isolation:
    """How this machine's sandboxes are isolated, as a probe sandbox found it."""

    network: str  # "namespace", "user-namespace" or "unavailable" (seccomp refuses sockets anyway)
    user: str  # "uid N" (its own), "root without capabilities", or "the server's user"
    landlock: int  # the kernel's Landlock ABI version (0: none)
    seccomp: bool
    uid_base: int  # what sandboxes are started with (0: no user of their own)
    problem: str | None = None  # why a probe failed, if one did
    without_own_user: str | None = None  # why a root server's sandboxes keep root's user id, if they do
    runtime: str = "readable"  # or "preloaded": the sandbox's user cannot read it (loaded before the change)
    runtimes: tuple[str, ...] = ()  # those whose tiny model the probe loaded and ran

    @property
    def missing(self) -> list[str]:
        """What full isolation lacks here, each with what to do about it."""
        if self.problem:
            return [f"a sandbox that starts (the probe sandbox failed: {self.problem})"]
        missing = []
        if not self.landlock:
            missing.append("Landlock, which keeps sandboxes from files their user may read (Linux 5.13 or later, "
                           "with landlock in its lsm= boot parameter)")
        if not self.seccomp:
            missing.append("seccomp, which keeps sandboxes from other processes and the network (libseccomp2)")
        if self.without_own_user:
            missing.append(f"a user id of its own: {self.without_own_user}")
        return missing

    @property
    def full(self) -> bool:
        return not self.missing

    def describe(self) -> str:
        if self.problem:
            return f"NOT isolated: {self.problem}"
        found = (f"Landlock ABI {self.landlock}, seccomp, network {self.network}, "
                 f"runs as {'a user id of its own' if self.uid_base else self.user}")
        if self.runtime == "preloaded":
            found += " (which cannot read its runtime: it uses what its fork server loaded before)"
        return f"{found}; NOT fully isolated, missing {'; and '.join(self.missing)}" if self.missing else found

    def check(self, limits: SandboxLimits) -> Isolation:
        """This isolation, or IsolationUnavailable if the limits require full isolation and it is not."""
        if limits.require_isolation and not self.full:
            raise IsolationUnavailable(f"uploaded models are not run here: the sandbox is {self.describe()} "
                                       "(set LEAGUE_SANDBOX_REQUIRE_ISOLATION=false to run them anyway)")
        return self

    def to_dict(self) -> dict:
        return {"full": self.full, "missing": self.missing, "network": self.network,
                "user": "own user id" if self.uid_base else self.user, "landlock": self.landlock,
                "seccomp": self.seccomp, "runtime": self.runtime, "runtimes": list(self.runtimes),
                "problem": self.problem}


_isolation_lock = threading.Lock()
_isolation: dict[int, Isolation] = {}  # by uid_base


def sandbox_isolation(uid_base: int = SandboxLimits.uid_base) -> Isolation:
    """This machine's sandbox isolation, found once per process (and uid_base) by probe sandboxes
    started as every sandbox is: with a user id of their own if we are root, else as this process's
    user."""
    with _isolation_lock:
        if uid_base not in _isolation:
            found = _isolation[uid_base] = _probe_isolation(uid_base if os.geteuid() == 0 else 0)
            (log.info if found.full else log.error)("sandbox isolation: %s", found.describe())
        return _isolation[uid_base]


def isolation(limits: SandboxLimits) -> Isolation:
    """The isolation sandboxes get; IsolationUnavailable if the limits require full isolation and
    this machine cannot give it."""
    return sandbox_isolation(limits.uid_base).check(limits)


def _probe_isolation(uid_base: int) -> Isolation:
    root, without_own_user = os.geteuid() == 0, None
    found = _run_probe(uid_base)
    if root and not uid_base:
        without_own_user = ("LEAGUE_SANDBOX_UID_BASE is 0, so sandboxes run as root without capabilities, which "
                            "still owns root's files and processes: unset it (each sandbox then runs as "
                            f"{SandboxLimits.uid_base} + its pid)")
    elif root and isinstance(found, str):
        without_own_user = (f"with one, the probe sandbox failed ({found}), so sandboxes run as root without "
                            "capabilities, which still owns root's files and processes: run the server as an "
                            "ordinary user, or from a Python every user may read (league/server/README.md, "
                            "\"Sandbox users\")")
        log.warning("sandboxes keep root's user id, without capabilities: with a user id of their own they "
                    "cannot load models (%s)", found)
        uid_base, found = 0, _run_probe(0)
    if isinstance(found, str):
        return Isolation("unknown", "unknown", 0, False, 0, problem=found)
    return Isolation(found["network"], found["user"], found["landlock"], found["seccomp"], uid_base,
                     without_own_user=without_own_user, runtime=found["runtime"], runtimes=tuple(found["runtimes"]))


def _run_probe(uid_base: int) -> dict | str:
    """Sandboxes without a model, one from each runtime's fork server: confined as sandboxes are,
    each loads and runs a tiny model of its runtime and says how it is isolated. Their findings
    together (a dict), or the first failure (the reason)."""
    found = [_probe_one(runtime, uid_base) for runtime in installed_runtimes() or [".onnx"]]
    failures = [one for one in found if isinstance(one, str)]
    if failures:
        return failures[0]
    return {**found[0], "runtimes": sorted({kind for one in found for kind in one["runtimes"]}),
            "runtime": "preloaded" if any(one["runtime"] == "preloaded" for one in found) else "readable"}


def _probe_one(runtime: str, uid_base: int) -> dict | str:
    workdir = Path(tempfile.mkdtemp(prefix="league-probe-"))
    try:
        proc = ForkServer.of_this_thread(runtime).spawn(["--probe", "0", "600", str(uid_base)], workdir,
                                                        _child_environment(workdir))
        with proc.stdout, proc.stderr, proc.stdin:
            tag, message = proc.stdout.read(1), proc.stdout.read()
            errors = proc.stderr.read().decode(errors="replace").strip()
        proc.wait()
    except SandboxFailure as failure:
        return failure.reason
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    text = message[LENGTH.size:].decode(errors="replace")
    if tag != b"R":
        lines = (text or errors).strip().splitlines()
        return lines[-1] if lines else "the probe sandbox died"
    return json.loads(text)["isolation"]


def installed_runtimes() -> list[str]:
    """The model suffixes whose runtime is installed here (so in sandboxes)."""
    return [suffix for suffix, installed in child.RUNTIMES.items() if installed]

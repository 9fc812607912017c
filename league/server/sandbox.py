"""Run untrusted models in sandbox processes; the worker and the API never load a model themselves.

`SandboxedAgent` is a `league.agents.Agent` whose model lives in a child process
(league/server/sandbox_child.py): the worker runs `league.evaluation.metrics_run` (and, later,
`race`) on it unchanged. Each call sends the observation batch as raw float32 bytes and waits
for the actions under a wall-clock deadline: `step_deadline` per call, plus a bank of
`first_call_allowance` spent by calls that overrun it (warm-up, JIT). A call past its deadline,
a crash, a NaN or a model exception raises `AgentError(reason)` -- a DNF for that episode -- and a
dead or killed child is restarted for the next episode, at most `max_restarts` times.

Isolation of the child: a private temporary directory holding a copy of the model (its
working directory; no path to the data directory or the database is ever given to it), no
inherited file descriptors but its pipes, a clean environment (no proxies, one thread), then,
done by the child itself: rlimits (CPU, address space, files), a new network namespace, and
the `sandbox_user` instead of root. See sandbox_child.py.

Starting: each thread that starts sandboxes has a `ForkServer`, a sandbox_child.py process that
has imported numpy, onnx and onnxruntime once and forks a sandbox per model (one start is a fork and a model
load, ~0.03 s, instead of a new interpreter, ~0.25 s). The server dies with its thread and takes
its sandboxes with it (the kernel's parent-death signal, which follows the starting thread).
Sandboxes run on the CPUs their thread may use when they start (see league.server.placement).
"""
from __future__ import annotations

import contextlib
import functools
import json
import os
import pwd
import select
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from league.agents import Agent, AgentError, check_actions, dry_run_observations
from league.server import sandbox_child
from league.server.config import Settings

CHILD_SCRIPT = Path(sandbox_child.__file__).resolve()
HEADER, LENGTH = sandbox_child.HEADER, sandbox_child.LENGTH
MAX_MESSAGE = 65536
READ_CHUNK = 65536
FORK_SERVER_TIMEOUT_S = 60.0  # its imports on a busy machine
DRY_RUN_CALLS = 24  # parent-side dry run: enough calls to see a model's steady speed
DRY_RUN_WARMUP = 4  # calls not counted in that speed (first calls are slower)


@dataclass(frozen=True)
class SandboxLimits:
    memory_mb: int = 512
    cpu_seconds: int = 600
    step_deadline_s: float = 0.020
    first_call_allowance_s: float = 1.0
    episode_deadline_s: float = 60.0
    load_timeout_s: float = 30.0
    user: str | None = "nobody"
    max_restarts: int = 3
    log_limit: int = 16 * 1024

    @classmethod
    def from_settings(cls, settings: Settings) -> SandboxLimits:
        return cls(memory_mb=settings.sandbox_memory_mb, cpu_seconds=settings.sandbox_cpu_seconds,
                   step_deadline_s=settings.step_deadline_ms / 1000,
                   first_call_allowance_s=settings.first_call_allowance_ms / 1000,
                   episode_deadline_s=settings.episode_deadline_s, load_timeout_s=settings.load_timeout_s,
                   user=settings.sandbox_user, max_restarts=settings.sandbox_max_restarts,
                   log_limit=settings.log_limit_kb * 1024)


class SandboxFailure(Exception):
    """The child failed; `fatal` when it is dead or was killed (a new one is needed)."""

    def __init__(self, reason: str, fatal: bool, timed_out: bool = False):
        super().__init__(reason)
        self.reason, self.fatal, self.timed_out = reason, fatal, timed_out


class LogBuffer:
    """What sandboxes printed: the first and the last bytes of it, with a marker for the cut."""

    def __init__(self, limit: int):
        self.head_limit, self.tail_limit = limit // 4, limit - limit // 4
        self.head, self.tail, self.dropped = bytearray(), bytearray(), 0
        self._lock = threading.Lock()

    def write(self, data: bytes) -> None:
        with self._lock:
            room = self.head_limit - len(self.head)
            self.head += data[:room]
            self.tail += data[max(room, 0):]
            if len(self.tail) > self.tail_limit:
                self.dropped += len(self.tail) - self.tail_limit
                del self.tail[: len(self.tail) - self.tail_limit]

    def note(self, text: str) -> None:
        self.write(f"[sandbox] {text}\n".encode())

    def text(self) -> str:
        with self._lock:
            cut = f"\n[... {self.dropped} bytes cut ...]\n".encode() if self.dropped else b""
            return (bytes(self.head) + cut + bytes(self.tail)).decode("utf-8", errors="replace")


class SandboxProcess:
    """One child process serving one model."""

    def __init__(self, model_file: Path, model_kind: str, limits: SandboxLimits, log: LogBuffer):
        self.limits, self.log = limits, log
        self.workdir = Path(tempfile.mkdtemp(prefix="league-sandbox-"))
        model_name = "model.onnx" if model_kind == "onnx" else "model.pt"
        shutil.copyfile(model_file, self.workdir / model_name)
        user = _usable_sandbox_user(limits.user)
        _hand_over(self.workdir, user)
        args = [model_name, str(limits.memory_mb), str(limits.cpu_seconds), user or ""]
        self.proc = ForkServer.of_this_thread().spawn(args, self.workdir, _child_environment(self.workdir))
        self._out = self.proc.stdout.fileno()
        os.set_blocking(self._out, False)
        self._poller = select.poll()
        self._poller.register(self._out, select.POLLIN)
        self._unread = bytearray()
        self._log_thread = threading.Thread(target=self._copy_log, daemon=True)
        self._log_thread.start()
        self.ready = self._await_ready()

    def _copy_log(self) -> None:
        for chunk in iter(lambda: self.proc.stderr.read1(65536), b""):
            self.log.write(chunk)

    def _await_ready(self) -> dict:
        deadline = time.monotonic() + self.limits.load_timeout_s
        try:
            tag, payload = self._read_message(deadline, expected=(b"R", b"E"))
        except SandboxFailure as failure:
            if failure.timed_out:
                raise SandboxFailure(f"the model did not load and pass its dry run within "
                                     f"{self.limits.load_timeout_s:g} s (a model must answer in "
                                     f"{self.limits.step_deadline_s * 1000:g} ms)", fatal=True) from failure
            raise
        if tag == b"E":
            raise SandboxFailure(payload.decode("utf-8", errors="replace"), fatal=True)
        return json.loads(payload)

    def send_observations(self, obs: np.ndarray) -> None:
        obs = np.ascontiguousarray(obs, dtype="<f4")
        self._send(HEADER.pack(b"I", obs.shape[0], obs.shape[1]) + obs.tobytes())

    def receive_actions(self, deadline: float) -> np.ndarray:
        tag, payload = self._read_message(deadline, expected=(b"A", b"E"))
        if tag == b"E":
            raise SandboxFailure(payload.decode("utf-8", errors="replace"), fatal=False)
        return payload

    def _send(self, data: bytes) -> None:
        try:
            self.proc.stdin.write(data)
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError) as error:
            raise SandboxFailure(self._death_reason(), fatal=True) from error

    def _read_message(self, deadline: float, expected: tuple[bytes, ...]) -> tuple[bytes, object]:
        tag = self._read_exact(1, deadline)
        if tag not in expected:
            self.kill()
            raise SandboxFailure(f"sandbox protocol error (message {tag!r})", fatal=True)
        if tag == b"A":
            n, d = HEADER.unpack(tag + self._read_exact(8, deadline))[1:]
            if d != 2 or n > sandbox_child.MAX_BATCH:
                self.kill()
                raise SandboxFailure(f"sandbox protocol error (actions {n}x{d})", fatal=True)
            return tag, np.frombuffer(self._read_exact(n * d * 4, deadline), dtype="<f4").reshape(n, d)
        (length,) = LENGTH.unpack(self._read_exact(LENGTH.size, deadline))
        if length > MAX_MESSAGE:
            self.kill()
            raise SandboxFailure("sandbox protocol error (message too long)", fatal=True)
        return tag, self._read_exact(length, deadline)

    def _read_exact(self, size: int, deadline: float) -> bytes:
        """`size` bytes of the child's answers, within the deadline. Reads are buffered and
        non-blocking: an answer that is already in the pipe costs one read, no poll."""
        while len(self._unread) < size:
            try:
                chunk = os.read(self._out, max(READ_CHUNK, size - len(self._unread)))
            except BlockingIOError:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not self._poller.poll(remaining * 1000):
                    self.kill()
                    raise SandboxFailure("deadline exceeded", fatal=True, timed_out=True) from None
                continue
            if not chunk:
                raise SandboxFailure(self._death_reason(), fatal=True)
            self._unread += chunk
        data = bytes(self._unread[:size])
        del self._unread[:size]
        return data

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

    def close(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            self.proc.stdin.close()
        self.kill()  # nothing in the child is worth its slow interpreter shutdown
        self._log_thread.join(timeout=2)
        self.proc.stdout.close()
        self.proc.stderr.close()
        shutil.rmtree(self.workdir, ignore_errors=True)


class ForkServer:
    """sandbox_child.py's fork server: one per thread that starts sandboxes, since the kernel's
    parent-death signal follows the thread that started a process; it ends with that thread."""

    _threads = threading.local()

    @classmethod
    def of_this_thread(cls) -> ForkServer:
        server = getattr(cls._threads, "server", None)
        if server is None or server.proc.poll() is not None:
            server = cls._threads.server = cls()
        return server

    def __init__(self):
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        home = Path(tempfile.gettempdir())
        with theirs:
            self.proc = subprocess.Popen(
                [sys.executable, "-s", "-B", "-P", str(CHILD_SCRIPT), "--fork-server", str(theirs.fileno())],
                cwd="/", env=_child_environment(home), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                pass_fds=[theirs.fileno()], start_new_session=True)
        self.control = ours
        self.control.settimeout(FORK_SERVER_TIMEOUT_S)
        self.cpus = os.sched_getaffinity(0)  # the thread's, inherited by the server
        self._lock = threading.Lock()

    def spawn(self, args: list[str], workdir: Path, env: dict[str, str]) -> ForkedProcess:
        """A sandbox process running sandbox_child.py `args` in `workdir`, with pipes to its stdio,
        on the CPUs the calling thread may use now (league.server.placement moves job threads)."""
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


def _usable_sandbox_user(user: str | None) -> str | None:
    """Drop root only to an existing user who can read this Python installation (a pyenv under
    /root cannot be read by `nobody`; a Docker image's /usr/local can)."""
    if not user or os.geteuid() != 0 or not _others_can_read(Path(np.__file__)):
        return None
    try:
        pwd.getpwnam(user)
    except KeyError:
        return None
    return user


def _others_can_read(path: Path) -> bool:
    if not path.stat().st_mode & stat.S_IROTH:
        return False
    return all(parent.stat().st_mode & stat.S_IXOTH for parent in path.resolve().parents)


def _hand_over(workdir: Path, user: str | None) -> None:
    """The sandbox user owns its directory and nothing else of ours."""
    if user:
        entry = pwd.getpwnam(user)
        for path in (workdir, *workdir.iterdir()):
            os.chown(path, entry.pw_uid, entry.pw_gid)
    os.chmod(workdir, 0o700)


def _child_environment(workdir: Path) -> dict[str, str]:
    """No proxies, no credentials, no PYTHONPATH of ours: only what Python and one-thread math need."""
    return {"PATH": os.defpath, "HOME": str(workdir), "TMPDIR": str(workdir), "LANG": "C.UTF-8",
            "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MALLOC_ARENA_MAX": "2",
            "ORT_DISABLE_TELEMETRY": "1"}


class SandboxedAgent(Agent):
    """An Agent whose model runs in a sandbox process, with deadlines and restarts (see module doc)."""

    kind = "sandbox"

    def __init__(self, model_file: Path, model_kind: str, limits: SandboxLimits, *, name: str = "submission",
                 log: LogBuffer | None = None, cancel: threading.Event | None = None):
        self.limits, self.model_file, self.model_kind = limits, Path(model_file), model_kind
        self.log = log or LogBuffer(limits.log_limit)
        self.cancel = cancel or threading.Event()
        self.restarts, self.last_failure = 0, None
        self.call_times: list[float] = []
        self._process: SandboxProcess | None = None
        ready = self._start()
        super().__init__(ready["obs_dim"], name)
        self.network = ready["network"]
        self.episode_time = 0.0

    def _start(self) -> dict:
        try:
            self._process = SandboxProcess(self.model_file, self.model_kind, self.limits, self.log)
        except SandboxFailure as failure:
            self._process = None
            self.log.note(f"refused: {failure.reason}")
            raise AgentError(failure.reason) from failure
        self.bank = self.limits.first_call_allowance_s
        self.log.note(f"started: network {self._process.ready['network']}, memory cap +{self.limits.memory_mb} MB, "
                      f"step deadline {self.limits.step_deadline_s * 1000:g} ms")
        return self._process.ready

    def new_episode(self) -> None:
        """Reset the per-episode clock (metrics_run's on_episode calls it)."""
        self.episode_time = 0.0

    def _act(self, obs: np.ndarray) -> np.ndarray:
        return self._send(obs)()

    def request(self, obs: np.ndarray) -> Callable[[], np.ndarray]:
        """Send the observations now; the result reads the answer (a race asks all its cars first)."""
        obs = self._check_observations(obs)
        try:
            receive = self._send(obs)
        except AgentError as error:
            return functools.partial(_raise, error)
        return lambda: check_actions(receive(), batch=obs.shape[0])

    def _send(self, obs: np.ndarray) -> Callable[[], np.ndarray]:
        """Send a batch; return the function that waits for its answer within the call's budget."""
        if self.cancel.is_set():
            raise AgentError("the evaluation was cancelled")
        process = self._live_process()
        episode_left = self.limits.episode_deadline_s - self.episode_time
        if episode_left <= 0:
            raise AgentError(f"the model used more than {self.limits.episode_deadline_s:g} s in this episode")
        budget = min(self.limits.step_deadline_s + self.bank, episode_left)
        started = time.monotonic()
        try:
            process.send_observations(obs)
        except SandboxFailure as failure:
            self._account(time.monotonic() - started)
            raise AgentError(self._failure_reason(failure, budget, episode_left)) from failure

        def receive() -> np.ndarray:
            try:
                return process.receive_actions(started + budget)
            except SandboxFailure as failure:
                raise AgentError(self._failure_reason(failure, budget, episode_left)) from failure
            finally:
                self._account(time.monotonic() - started)

        return receive

    def _account(self, elapsed: float) -> None:
        self.call_times.append(elapsed)
        self.episode_time += elapsed
        self.bank = max(0.0, self.bank - max(0.0, elapsed - self.limits.step_deadline_s))

    def _failure_reason(self, failure: SandboxFailure, budget: float, episode_left: float) -> str:
        if failure.fatal:
            self._process.close()
            self._process = None
        if not failure.timed_out:
            reason = failure.reason
        elif budget >= episode_left:
            reason = f"the model used more than {self.limits.episode_deadline_s:g} s in this episode"
        else:
            reason = (f"the model did not answer within its {self.limits.step_deadline_s * 1000:g} ms step deadline "
                      f"(allowance left: {self.bank * 1000:.0f} ms)")
        self.last_failure = reason
        self.log.note(reason)
        return reason

    def _live_process(self) -> SandboxProcess:
        if self._process is not None:
            return self._process
        if self.restarts >= self.limits.max_restarts:
            raise AgentError(f"the agent was stopped after {self.restarts + 1} failures; last: {self.last_failure}")
        self.restarts += 1
        self._start()
        return self._process

    def close(self) -> None:
        if self._process is not None:
            self._process.close()
            self._process = None


def _raise(error: Exception):
    raise error


# --------------------------------------------------------------------------- validation


@dataclass(frozen=True)
class ValidationReport:
    ok: bool
    obs_dim: int | None
    error: str | None
    log: str
    ms_per_call: float | None = None


def validate_model(model_file: Path, model_kind: str, limits: SandboxLimits) -> ValidationReport:
    """Static checks, load and the toolkit's dry run (in the child), then a timed dry run from here."""
    log = LogBuffer(limits.log_limit)
    strict = SandboxLimits(**{**limits.__dict__, "max_restarts": 0})
    try:
        with SandboxedAgent(model_file, model_kind, strict, log=log) as agent:
            speed = _timed_dry_run(agent)
    except AgentError as error:
        return ValidationReport(False, None, error.reason, log.text())
    if speed > limits.step_deadline_s:
        reason = (f"the model is too slow: {speed * 1000:.1f} ms per call, the limit is "
                  f"{limits.step_deadline_s * 1000:g} ms")
        return ValidationReport(False, None, reason, log.text(), speed * 1000)
    return ValidationReport(True, agent.obs_dim, None, log.text(), speed * 1000)


def _timed_dry_run(agent: SandboxedAgent) -> float:
    """Median time of a call after warm-up, on plausible, varied observations (batches of 1 and 4)."""
    rng = np.random.default_rng(0)
    for i in range(DRY_RUN_CALLS):
        batch = 4 if i % 6 == 5 else 1
        obs = dry_run_observations(agent.obs_dim, batch)
        agent(obs * rng.uniform(0.5, 1.5, obs.shape).astype(np.float32))
    return float(np.median(agent.call_times[DRY_RUN_WARMUP:]))

"""The sandbox process: loads one untrusted model and answers observation batches over a pipe.

Forked by the fork server (`python -s -B -P sandbox_child.py --fork-server FD`, which
league.server.sandbox starts once per job thread and which has imported the runtimes) as if run
as `sandbox_child.py MODEL MEMORY_MB CPU_S USER` in a private temporary directory that holds
only the model. Before it reads the model it limits itself (CPU time, open files, file size, no
core dumps), leaves the network (a new, empty network namespace), drops root to USER, and forbids
regaining privileges; after its runtime is imported it caps its address space. Inference is
single-threaded.

Protocol (little endian; the parent sends only numbers, never a pickle):
    parent -> child  b"I" u32 n u32 d, then n*d float32     an observation batch
    child -> parent  b"R" u32 len, JSON                       ready: {"obs_dim", "kind", "network"}
                     b"A" u32 n u32 2, then n*2 float32       actions
                     b"E" u32 len, UTF-8                      the model failed: the reason
The child exits at end of input (the parent closed the pipe or died).
"""
from __future__ import annotations

import ctypes
import importlib
import json
import os
import resource
import signal
import struct
import sys
import types
from pathlib import Path

HEADER = struct.Struct("<cII")  # tag, n, d
LENGTH = struct.Struct("<I")
MAX_BATCH = 4096
LEAGUE_DIR = Path(__file__).resolve().parent.parent
CLONE_NEWNET, CLONE_NEWUSER = 0x40000000, 0x10000000
PR_SET_PDEATHSIG, PR_SET_NO_NEW_PRIVS = 1, 38
MAX_OPEN_FILES = 64
MAX_FILE_WRITE = 1024 * 1024  # bytes a model may write (it has no reason to write at all)


# --------------------------------------------------------------------------- isolation


def take_protocol_fds() -> tuple[int, int]:
    """Keep stdin/stdout for the protocol on private fds; whatever the model prints goes to stderr."""
    proto_in, proto_out = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(2, 1)
    os.close(devnull)
    sys.stdout = sys.stderr
    return proto_in, proto_out


def limit_resources(cpu_seconds: int) -> None:
    resource.setrlimit(resource.RLIMIT_CPU, (cpu_seconds, cpu_seconds + 1))
    resource.setrlimit(resource.RLIMIT_NOFILE, (MAX_OPEN_FILES, MAX_OPEN_FILES))
    resource.setrlimit(resource.RLIMIT_FSIZE, (MAX_FILE_WRITE, MAX_FILE_WRITE))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def isolate_network() -> str:
    """Move into a new network namespace (no interfaces but a down loopback): no connection can be made.

    Needs root or unprivileged user namespaces; where neither is allowed (e.g. a default
    Docker container), the sandbox runs with proxies unset and reports "unavailable".
    """
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(CLONE_NEWNET) == 0:
        return "namespace"
    if libc.unshare(CLONE_NEWUSER | CLONE_NEWNET) == 0:
        return "user-namespace"
    return "unavailable"


def drop_privileges(user: str | None) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)  # the worker died: so does its sandbox
    if user and os.geteuid() == 0:
        import pwd

        entry = pwd.getpwnam(user)
        os.setgroups([])
        os.setgid(entry.pw_gid)
        os.setuid(entry.pw_uid)
    libc.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0)


def cap_address_space(extra_mb: int) -> None:
    """The runtime's own footprint (torch maps ~0.7 GB) plus what the model may allocate."""
    resource.setrlimit(resource.RLIMIT_AS, (virtual_memory_size() + extra_mb * 1024 * 1024,) * 2)


def virtual_memory_size() -> int:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


def single_thread_environment() -> None:
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[name] = "1"


# --------------------------------------------------------------------------- loading


def import_league_module(name: str) -> types.ModuleType:
    """Import league.<name> without league/__init__.py, which loads the whole simulator (~0.5 s,
    scipy and gymnasium) that a sandbox never uses."""
    if "league" not in sys.modules:
        package = types.ModuleType("league")
        package.__path__ = [str(LEAGUE_DIR)]
        sys.modules["league"] = package
    return importlib.import_module(f"league.{name}")


def load_model(model_path: Path, memory_mb: int):
    """Static checks, then the toolkit's loader (which dry-runs the model) under the memory cap."""
    agents = import_league_module("agents")
    checks = import_league_module("server.model_checks")
    if model_path.suffix == ".onnx":
        checks.check_onnx(model_path)
        agents.import_onnxruntime().disable_telemetry_events()  # before the cap: its footprint is not the model's

        cap_address_space(memory_mb)
        return agents.load_agent(model_path, name="submission")
    checks.check_torchscript_archive(model_path)
    torch = _import_torch()
    cap_address_space(memory_mb)
    module = torch.jit.load(str(model_path), map_location="cpu")
    checks.check_torchscript_graph(module)
    return agents.torch_module_agent(module, name="submission")


def _import_torch():
    import warnings

    import torch

    torch.set_num_threads(1)
    torch.set_num_interop_threads(1)
    warnings.simplefilter("ignore", DeprecationWarning)  # torch.jit is in maintenance, still supported
    return torch


def failure_reason(error: BaseException, memory_mb: int) -> str:
    """One line for the student; the full message goes to the log (stderr)."""
    print(f"{type(error).__name__}: {error}", file=sys.stderr, flush=True)
    reason = getattr(error, "reason", None) or f"{type(error).__name__}: {' '.join(str(error).split())[:300]}"
    if isinstance(error, MemoryError) or "alloc" in reason.lower():
        return f"out of memory (the cap is {memory_mb} MB): {reason}"
    return reason


# --------------------------------------------------------------------------- fork server


def fork_server(control_fd: int) -> int:
    """Import the runtimes once, then fork one sandbox per request: a start costs a fork and a
    model load instead of a new interpreter and its imports (~0.25 s of CPU per sandbox).

    Requests on the control socket (SOCK_SEQPACKET, JSON): {"args", "workdir", "env"} with the
    sandbox's stdin, stdout and stderr as SCM_RIGHTS fds -> {"pid"}; {"wait": pid} -> {"status":
    exit code, -signal, or null while it runs}. A child stays a zombie until it is waited for, so
    its pid cannot be reused while the parent holds it. Ends when the control socket closes.
    """
    import socket

    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)  # the worker's thread ended: so does this server
    single_thread_environment()  # before numpy: a fork must find one thread
    preload_runtimes()
    control = socket.socket(fileno=control_fd)
    while True:
        message, fds, _, _ = socket.recv_fds(control, 65536, 3)
        if not message:
            return 0
        request = json.loads(message)
        if "wait" in request:
            pid, status = os.waitpid(request["wait"], os.WNOHANG)
            reply = {"status": os.waitstatus_to_exitcode(status) if pid else None}
        else:
            reply = {"pid": fork_sandbox(request, fds, control)}
        control.send(json.dumps(reply).encode())


def preload_runtimes() -> None:
    """What every ONNX sandbox imports, all of which start no thread (onnxruntime only with its
    telemetry off; torch is imported by each TorchScript sandbox after the fork)."""
    import contextlib

    agents = import_league_module("agents")  # numpy
    import_league_module("server.model_checks")
    with contextlib.suppress(agents.AgentError, ImportError):  # without the onnx extra: TorchScript only
        import onnx  # noqa: F401  (the static checks)

        agents.import_onnxruntime().disable_telemetry_events()


def fork_sandbox(request: dict, fds: list[int], control) -> int:
    pid = os.fork()
    if pid:
        for fd in fds:
            os.close(fd)
        return pid
    code, server = 1, os.getppid()
    try:
        control.close()
        os.setsid()
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        os.closerange(3, max(3, *(int(fd) for fd in os.listdir("/proc/self/fd"))) + 1)  # nothing else of ours
        os.chdir(request["workdir"])
        os.environ.clear()
        os.environ.update(request["env"])
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)  # the server dies: so do we
        if os.getppid() == server:  # (it did not die before the line above)
            code = run_sandbox(request["args"])
    except BaseException:
        import traceback

        traceback.print_exc()
    finally:
        sys.stderr.flush()
        os._exit(code)


# --------------------------------------------------------------------------- protocol


class Reader:
    """Buffered reads of the parent's requests: a request written at once is read at once."""

    def __init__(self, fd: int):
        self.fd, self.unread = fd, bytearray()

    def read_exact(self, size: int) -> bytes:
        """`size` bytes, or b"" at the end of input."""
        while len(self.unread) < size:
            chunk = os.read(self.fd, max(65536, size - len(self.unread)))
            if not chunk:
                return b""
            self.unread += chunk
        data = bytes(self.unread[:size])
        del self.unread[:size]
        return data


def send(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def send_text(fd: int, tag: bytes, text: str) -> None:
    payload = text.encode("utf-8", errors="replace")[:65536]
    send(fd, tag + LENGTH.pack(len(payload)) + payload)


def serve(agent, proto_in: int, proto_out: int, memory_mb: int) -> None:
    import numpy as np

    requests = Reader(proto_in)
    while True:
        header = requests.read_exact(HEADER.size)
        if not header:
            return
        tag, n, d = HEADER.unpack(header)
        if tag != b"I" or n > MAX_BATCH or d != agent.obs_dim:
            send_text(proto_out, b"E", f"sandbox protocol error: request {tag!r} {n}x{d}")
            return
        obs = np.frombuffer(bytearray(requests.read_exact(n * d * 4)), dtype="<f4").reshape(n, d)  # writable
        try:
            actions = np.ascontiguousarray(agent(obs), dtype="<f4")
        except Exception as error:  # the model's failure is an answer, not the sandbox's end
            send_text(proto_out, b"E", failure_reason(error, memory_mb))
            continue
        send(proto_out, HEADER.pack(b"A", actions.shape[0], actions.shape[1]) + actions.tobytes())


def main(argv: list[str]) -> int:
    if argv[1:2] == ["--fork-server"]:
        return fork_server(int(argv[2]))
    return run_sandbox(argv[1:])


def run_sandbox(args: list[str]) -> int:
    """Serve one model: MODEL MEMORY_MB CPU_S USER, the protocol on stdin/stdout."""
    model_path, memory_mb, cpu_seconds, user = Path(args[0]), int(args[1]), int(args[2]), args[3] or None
    proto_in, proto_out = take_protocol_fds()
    limit_resources(cpu_seconds)
    network = isolate_network()
    drop_privileges(user)
    single_thread_environment()
    try:
        agent = load_model(model_path, memory_mb)
    except BaseException as error:  # whatever the file did, it is the reason it is refused
        send_text(proto_out, b"E", failure_reason(error, memory_mb))
        return 1
    ready = {"obs_dim": agent.obs_dim, "kind": agent.kind, "network": network}
    send_text(proto_out, b"R", json.dumps(ready))
    serve(agent, proto_in, proto_out, memory_mb)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

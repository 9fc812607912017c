"""The sandbox process: loads one untrusted model and answers observation batches over a pipe.

Forked by a fork server (`python -s -B -P child.py --fork-server FD RUNTIME`, which
league.server.sandbox.process starts once per job thread and runtime, and which has loaded and run a
tiny model of its runtime) as if run as `child.py MODEL MEMORY_MB CPU_S USER` in a private temporary
directory that holds only the model. Before it reads the model it limits itself (CPU time, open
files, file size, no core dumps), leaves the network (a new, empty network namespace), drops root
to USER, and forbids regaining privileges; after its runtime is imported it caps its address
space. Inference is single-threaded.

Protocol (little endian; the parent sends only numbers, never a pickle):
    parent -> child  b"I" u32 n u32 d, then n*d float32     an observation batch
    child -> parent  b"R" u32 len, JSON                       ready: {"isolation", "obs_dim"}
                     b"A" u32 n u32 2, then n*2 float32       actions
                     b"E" u32 len, UTF-8                      the model failed: the reason
The child exits at end of input (the parent closed the pipe or died).
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import importlib
import importlib.util
import json
import os
import resource
import signal
import struct
import sys
import sysconfig
import time
from pathlib import Path

HEADER = struct.Struct("<cII")  # tag, n, d
LENGTH = struct.Struct("<I")
MAX_BATCH = 4096
LEAGUE_DIR = Path(__file__).resolve().parents[2]
CLONE_NEWNET, CLONE_NEWUSER, CLONE_THREAD = 0x40000000, 0x10000000, 0x00010000
CLONE_NAMESPACES = (0x00020000, 0x04000000, 0x08000000, 0x10000000, 0x20000000, 0x40000000, 0x02000000, 0x00000080)
PR_SET_PDEATHSIG, PR_SET_NO_NEW_PRIVS = 1, 38
LINUX_CAPABILITY_VERSION_3 = 0x20080522
MAX_OPEN_FILES = 64
MAX_FILE_WRITE = 1024 * 1024  # bytes a model may write (it has no reason to write at all)
MAX_THREADS = 64  # of a sandbox's own user id
IDLE_BEFORE_PREPARING_S = 1.0  # a job thread's TorchScript server prepares torch once no request came for this long
# The runtimes installed here (so to sandboxes), by the suffix of the model file the server names them by
RUNTIMES = {suffix: all(importlib.util.find_spec(module) for module in modules)
            for suffix, modules in ((".onnx", ("onnx", "onnxruntime")), (".pt", ("torch",)))}
# Landlock (linux/landlock.h): the syscalls are 444-446 on every architecture; rights with the ABI
# version that introduced them
SYS_LANDLOCK_CREATE_RULESET = 444
LANDLOCK_CREATE_RULESET_VERSION, LANDLOCK_RULE_PATH_BENEATH = 1, 1
LANDLOCK_FS = {name: (1 << bit, 1) for bit, name in enumerate((
    "execute", "write_file", "read_file", "read_dir", "remove_dir", "remove_file", "make_char", "make_dir",
    "make_reg", "make_sock", "make_fifo", "make_block", "make_sym"))}
LANDLOCK_FS.update(refer=(1 << 13, 2), truncate=(1 << 14, 3), ioctl_dev=(1 << 15, 5))
LANDLOCK_NET_TCP = 0b11  # bind and connect: handled with no rule, so refused
LANDLOCK_SCOPES = 0b11  # abstract unix sockets and signals outside the sandbox
# Read-only besides this Python: shared libraries, the loader's cache, randomness, the CPU topology
SYSTEM_READ = ("/usr", "/lib", "/lib64", "/lib32", "/etc/ld.so.cache", "/dev/urandom", "/proc/cpuinfo", "/proc/stat",
               "/sys/devices/system/cpu")
DENIED_SYSCALLS = (
    "execve", "execveat", "fork", "vfork", "unshare", "setns",  # programs, processes, namespaces
    "ptrace", "process_vm_readv", "process_vm_writev", "process_madvise", "process_mrelease", "pidfd_open",
    "pidfd_getfd", "pidfd_send_signal", "kcmp", "kill", "tkill", "rt_sigqueueinfo", "rt_tgsigqueueinfo",
    "shmget", "shmat", "shmctl", "semget", "semop", "semtimedop", "semctl", "msgget", "msgsnd", "msgrcv", "msgctl",
    "mq_open", "mq_unlink", "mq_timedsend", "mq_timedreceive", "mq_notify", "mq_getsetattr",  # other processes
    "setsid", "setpgid",  # a session of its own is a scheduling group of its own (an autogroup, at nice 0)
    "socket", "socketpair",  # the network, unix sockets included (a database's socket file)
    "mount", "umount2", "pivot_root", "chroot", "open_tree", "move_mount", "fsopen", "fsconfig", "fsmount", "fspick",
    "mount_setattr", "open_by_handle_at", "name_to_handle_at",  # filesystems, and reading around Landlock
    "bpf", "perf_event_open", "userfaultfd", "io_uring_setup", "io_uring_enter", "io_uring_register",
    "kexec_load", "kexec_file_load", "init_module", "finit_module", "delete_module", "reboot", "swapon", "swapoff",
    "acct", "quotactl", "settimeofday", "clock_settime", "adjtimex", "clock_adjtime", "syslog", "personality",
    "keyctl", "add_key", "request_key",  # the kernel and its keyrings
    "setuid", "setgid", "setreuid", "setregid", "setresuid", "setresgid", "setfsuid", "setfsgid", "setgroups",
    "capset",  # identities, once the sandbox has its own
)
# System calls that act on the process one of their arguments names (0: the caller), and which argument:
# refused for every process but the sandbox itself, named 0 (its own pid and its threads' ids are
# refused like any other: the runtimes, on one thread, call these on 0 only).
ON_A_PROCESS = {"prlimit64": 0, "sched_setaffinity": 0, "sched_setattr": 0, "sched_setscheduler": 0,
                "sched_setparam": 0, "migrate_pages": 0, "move_pages": 0, "get_robust_list": 0,
                "setpriority": 1, "ioprio_set": 1}
# ... of which these say in their first argument what the second names: a process only, never a
# process group or a user (every process of the server's user)
PRIO_PROCESS, IOPRIO_WHO_PROCESS = 0, 1
ONLY_A_PROCESS = {"setpriority": PRIO_PROCESS, "ioprio_set": IOPRIO_WHO_PROCESS}
LIBC = ctypes.CDLL(None, use_errno=True)


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


def isolate_network(user_namespace: bool = True) -> str:
    """Move into a new network namespace (no interfaces but a down loopback): no connection can be made.

    Needs CAP_SYS_ADMIN, or (`user_namespace`) a user namespace of its own where the kernel allows
    unprivileged ones. Where neither works (e.g. Docker's default seccomp profile), the sandbox runs
    with proxies unset, seccomp refusing sockets, and reports "unavailable".
    """
    if LIBC.unshare(CLONE_NEWNET) == 0:
        return "namespace"
    if user_namespace and LIBC.unshare(CLONE_NEWUSER | CLONE_NEWNET) == 0:
        return "user-namespace"
    return "unavailable"


def become_sandbox_user(uid_base: int) -> str:
    """Leave root: to a user id of this sandbox's own (`uid_base` + its pid, unique on the machine
    while it runs) when `uid_base` is set, else to root without any capability. A process that is
    not root keeps its user; Landlock and seccomp confine it. Returns who the sandbox runs as."""
    if os.geteuid() != 0:
        return "the server's user"
    if uid_base:
        uid = uid_base + os.getpid()
        os.chown(".", uid, uid)  # its directory (the model is readable by any user)
        os.setgroups([])
        os.setresgid(uid, uid, uid)
        os.setresuid(uid, uid, uid)
        resource.setrlimit(resource.RLIMIT_NPROC, (MAX_THREADS, MAX_THREADS))  # per user: this sandbox's own
        return f"uid {uid}"
    drop_capabilities()
    return "root without capabilities"


def drop_capabilities() -> None:
    """Clear every capability set (capset(2)): root by number, but no power over what others own."""

    class Header(ctypes.Structure):
        _fields_ = [("version", ctypes.c_uint32), ("pid", ctypes.c_int)]

    class Data(ctypes.Structure):
        _fields_ = [("effective", ctypes.c_uint32), ("permitted", ctypes.c_uint32), ("inheritable", ctypes.c_uint32)]

    if LIBC.capset(ctypes.byref(Header(LINUX_CAPABILITY_VERSION_3, 0)), (Data * 2)()) != 0:
        raise OSError(ctypes.get_errno(), "capset failed: cannot drop root's capabilities")


def die_with_the_server(server: int) -> None:
    """The parent-death signal, set after leaving root (a change of user clears it), then a check that
    the server did not die before it was set."""
    LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != server:
        os._exit(1)
    LIBC.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0)


@functools.cache
def read_roots() -> tuple[str, ...]:
    """What a sandbox may read: this Python (its prefixes, standard library and site-packages, never
    a path a .pth file added), our package, the system's shared libraries, and the CPU description
    the runtimes read. Everything else (the data directory, other sandboxes, /etc, /tmp) is denied.
    Found once by the fork server (sysconfig's first answer costs a sandbox's start several ms)."""
    paths = sysconfig.get_paths()
    roots = {sys.base_prefix, sys.base_exec_prefix, paths["stdlib"], paths["platstdlib"], paths["purelib"],
             paths["platlib"], str(LEAGUE_DIR), *SYSTEM_READ}
    return tuple(sorted(root for root in roots if os.path.exists(root)))


def files_ruleset() -> tuple[int, int]:
    """Landlock's rules for the sandbox, as (ruleset fd, the kernel's Landlock ABI version): read-only
    access to `read_roots()`, its own directory (the working directory) read and write, /dev/null;
    nothing else. Where the kernel has them, also no TCP at all and no signal or abstract socket
    outside the sandbox. Built before the sandbox leaves root: the sandbox's own user may not be
    able to open the paths it names (a Python under a home only root may enter)."""
    abi = _landlock(0, None, 0, LANDLOCK_CREATE_RULESET_VERSION)
    fs_rights = sum(bit for bit, since in LANDLOCK_FS.values() if abi >= since)
    ruleset = LandlockRuleset(fs_rights, LANDLOCK_NET_TCP if abi >= 4 else 0, LANDLOCK_SCOPES if abi >= 6 else 0)
    fd = _landlock(0, ctypes.byref(ruleset), ctypes.sizeof(ruleset), 0)
    try:
        read_dir, read_file = LANDLOCK_FS["execute"][0] | LANDLOCK_FS["read_file"][0], LANDLOCK_FS["read_file"][0]
        read_dir |= LANDLOCK_FS["read_dir"][0]
        for root in (*read_roots(), "/proc/self"):
            _allow(fd, root, read_dir if os.path.isdir(root) else read_file)
        _allow(fd, ".", fs_rights)
        _allow(fd, os.devnull, read_file | LANDLOCK_FS["write_file"][0])
    except BaseException:
        os.close(fd)
        raise
    return fd, abi


def restrict_files(ruleset: int) -> None:
    """Enforce the rules of `files_ruleset()` on this process, for good (no_new_privs is set)."""
    try:
        _landlock(2, ruleset, 0)  # landlock_restrict_self
    finally:
        os.close(ruleset)


class LandlockRuleset(ctypes.Structure):
    _fields_ = [("handled_access_fs", ctypes.c_uint64), ("handled_access_net", ctypes.c_uint64),
                ("scoped", ctypes.c_uint64)]


class LandlockPathBeneath(ctypes.Structure):
    _pack_ = 1
    _fields_ = [("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32)]


def _allow(ruleset_fd: int, path: str, rights: int) -> None:
    fd = os.open(path, os.O_PATH | os.O_CLOEXEC)
    try:
        _landlock(1, ruleset_fd, LANDLOCK_RULE_PATH_BENEATH, ctypes.byref(LandlockPathBeneath(rights, fd)), 0)
    finally:
        os.close(fd)


def _landlock(call: int, *args) -> int:
    """landlock_create_ruleset (0), landlock_add_rule (1), landlock_restrict_self (2), checked."""
    result = LIBC.syscall(ctypes.c_long(SYS_LANDLOCK_CREATE_RULESET + call), *args)
    if result < 0:
        error = ctypes.get_errno()
        raise OSError(error, f"Landlock ({('create_ruleset', 'add_rule', 'restrict_self')[call]}): "
                             f"{os.strerror(error)}")
    return result


def restrict_syscalls() -> None:
    """seccomp: refuse (EPERM) what inference never needs -- running programs, new processes and
    namespaces, sockets, acting on other processes (signals, limits, priorities, CPUs, memory,
    tracing, IPC), sessions, mounts, kernel and identity changes."""
    import errno

    import pyseccomp as seccomp

    rules = syscall_rules()  # (a copy of the fork server's, in a sandbox it forked)
    own = os.getpid()
    rules.add_rule(seccomp.ERRNO(errno.EPERM), "tgkill", seccomp.Arg(0, seccomp.NE, own))  # signals to itself only
    rules.load()


@functools.cache
def syscall_rules():
    """The rules that name no process: built once per fork server, since libseccomp takes several ms
    of a sandbox's start for them. A system call ON_A_PROCESS is refused unless its argument is 0:
    the sandbox itself by the only name that is the same in every sandbox."""
    import errno

    import pyseccomp as seccomp

    rules = seccomp.SyscallFilter(seccomp.ALLOW)
    refuse = seccomp.ERRNO(errno.EPERM)
    for name in DENIED_SYSCALLS:
        with contextlib.suppress(RuntimeError, ValueError):  # a syscall this architecture does not have
            rules.add_rule(refuse, name)
    for name, argument in ON_A_PROCESS.items():
        if name in ONLY_A_PROCESS:
            rules.add_rule(refuse, name, seccomp.Arg(0, seccomp.NE, ONLY_A_PROCESS[name]))
        rules.add_rule(refuse, name, seccomp.Arg(argument, seccomp.NE, 0))
    rules.add_rule(refuse, "clone", seccomp.Arg(0, seccomp.MASKED_EQ, CLONE_THREAD, 0))  # threads, no processes
    for flag in CLONE_NAMESPACES:
        rules.add_rule(refuse, "clone", seccomp.Arg(0, seccomp.MASKED_EQ, flag, flag))
    rules.add_rule(seccomp.ERRNO(errno.ENOSYS), "clone3")  # its flags are out of reach: glibc falls back to clone
    return rules


def single_thread_environment() -> None:
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
        os.environ[name] = "1"


# --------------------------------------------------------------------------- loading


def load_model(model_path: Path, memory_mb: int | None):
    """The toolkit's checked load (league.validation.loading: static checks, then the loader, which
    dry-runs the model) under the memory cap (None: no cap, for the fork server's own tiny models)."""
    from league.validation.loading import load_checked

    return load_checked(model_path, memory_mb)


def tiny_onnx(path: Path) -> Path:
    """The heuristic driver as ONNX with its batch fixed to 1, which the loader then frees (as it
    does for many exports): loading it runs every step an ONNX model's load can take."""
    import onnx

    from league.agents import export_heuristic_onnx

    export_heuristic_onnx(path)
    model = onnx.load(str(path))
    for value in (*model.graph.input, *model.graph.output):
        value.type.tensor_type.shape.dim[0].dim_value = 1
    onnx.save(model, str(path))
    return path


def tiny_torchscript(path: Path) -> Path:
    """A small MLP, scripted as students export theirs."""
    from league.agents import export_torchscript
    from league.validation.loading import import_torch

    nn = import_torch().nn
    mlp = nn.Sequential(nn.Linear(5, 8), nn.Tanh(), nn.Linear(8, 2))
    return export_torchscript(mlp, path)


TINY_MODELS = {".onnx": tiny_onnx, ".pt": tiny_torchscript}
PREPARED: dict[str, bytes] = {}  # runtime (its models' suffix) -> the tiny model it ran in this process


def prepare_runtime(suffix: str) -> None:
    """Load and run a tiny model of this runtime here, through the code a sandbox runs. Its sandboxes,
    forked from here, then find everything they use imported and initialised: no sandbox repeats
    the imports (torch's cost more than an ONNX sandbox's whole run), and a sandbox whose own user
    cannot read this Python (installed under a home only root may enter) needs to read none of it."""
    if suffix in PREPARED or not RUNTIMES.get(suffix):
        return
    import tempfile

    with tempfile.TemporaryDirectory(prefix="league-runtime-") as folder:
        path = TINY_MODELS[suffix](Path(folder) / f"tiny{suffix}")
        run_tiny_model(path)
        PREPARED[suffix] = path.read_bytes()


def run_tiny_model(path: Path) -> None:
    from league.agents import dry_run_observations

    agent = load_model(path, memory_mb=None)
    agent(dry_run_observations(agent.obs_dim, 3))


# --------------------------------------------------------------------------- fork server


def fork_server(control_fd: int, runtime: str, prepare_when_idle: bool = False) -> int:
    """Prepare one runtime once (`runtime`, its models' suffix), then fork one sandbox per request:
    a start costs a fork and a model load instead of a new interpreter and its imports (~0.25 s of
    CPU per sandbox). One runtime per server: a fork copies the server's page tables, and an ONNX
    sandbox forked from a server that also holds torch starts in 1.7x the time.

    Requests on the control socket (SOCK_SEQPACKET, JSON): {"args", "workdir", "env"} with the
    sandbox's stdin, stdout and stderr as SCM_RIGHTS fds -> {"pid"}; {"wait": pid} -> {"status":
    exit code, -signal, or null while it runs}. A child stays a zombie until it is waited for, so
    its pid cannot be reused while the parent holds it. Ends when the control socket closes.
    ONNX is prepared at once; TorchScript before the first sandbox that needs it or, with
    `prepare_when_idle` (a worker's job threads), once no request came for IDLE_BEFORE_PREPARING_S.
    """
    import select
    import socket
    import traceback

    LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)  # the worker's thread ended: so does this server
    keep_our_nice_in_our_autogroup()  # (started in a session of its own)
    single_thread_environment()  # before numpy: a fork must find one thread
    preload_runtimes()
    if runtime == ".onnx":
        prepare_runtime(runtime)
    control = socket.socket(fileno=control_fd)
    unprepared = prepare_when_idle and runtime not in PREPARED
    while True:
        if unprepared and not select.select([control], [], [], IDLE_BEFORE_PREPARING_S)[0]:
            unprepared = False
            try:
                prepare_runtime(runtime)
            except Exception:  # tried again (and this server ends) when a sandbox needs it
                traceback.print_exc()
            continue
        message, fds, _, _ = socket.recv_fds(control, 65536, 3)
        if not message:
            return 0
        request = json.loads(message)
        if "wait" in request:
            pid, status = os.waitpid(request["wait"], os.WNOHANG)
            reply = {"status": os.waitstatus_to_exitcode(status) if pid else None}
        else:
            model = request["args"][0]
            prepare_runtime(runtime if model == "--probe" else Path(model).suffix)  # once, before its first sandbox
            reply = {"pid": fork_sandbox(request, fds, control)}
        control.send(json.dumps(reply).encode())


def preload_runtimes() -> None:
    """What every sandbox imports and the parts of its confinement that are the same in every
    sandbox: no runtime yet, and none of it starts a thread (nor do the runtimes, prepared next:
    onnxruntime only with its telemetry off)."""
    import encodings.cp437  # noqa: F401  (zipfile's, for names in archives that do not say UTF-8)
    import traceback  # noqa: F401  (a sandbox's unexpected failure is printed with it)

    read_roots()
    syscall_rules()
    for module in ("league.agents", "league.validation.loading", "league.validation.checks"):  # agents: numpy
        importlib.import_module(module)


def set_autogroup_nice(nice: int, pid: int | str = "self", wait_s: float = 2.0) -> None:
    """Linux schedules each session as one group (its autogroup), at nice 0 whatever its threads' nice
    values: a process leading a session of its own gives its group `nice`, or the API's session would
    share the CPU with it as an equal. Without CAP_SYS_ADMIN the kernel takes one such change per
    0.1 s on the whole machine and refuses the others (EAGAIN): tried again for `wait_s` at most."""
    end = time.monotonic() + wait_s
    while True:
        try:
            with open(f"/proc/{pid}/autogroup", "w") as autogroup:
                autogroup.write(str(nice))
            return
        except BlockingIOError:
            if time.monotonic() >= end:
                return
            time.sleep(0.02)
        except OSError:  # a kernel without autogroups: the threads' nice is the priority
            return


def keep_our_nice_in_our_autogroup() -> None:
    """A new session: its group gets the nice value we inherited from the job's thread."""
    set_autogroup_nice(os.getpriority(os.PRIO_PROCESS, 0))


def fork_sandbox(request: dict, fds: list[int], control) -> int:
    import gc

    # what the server holds (its runtimes' objects) out of the collector's reach, in the sandbox: a
    # collection there would write to every object's pages, copying them from the server's (fork)
    gc.freeze()
    pid = os.fork()
    if pid:
        for fd in fds:
            os.close(fd)
        return pid
    code, server = 1, os.getppid()
    try:
        control.close()
        # no session of its own: a sandbox shares its fork server's autogroup, set once at the
        # job's nice (the sandboxes of a heat, starting together, would each wait 0.1 s for theirs)
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        os.closerange(3, max(3, *(int(fd) for fd in os.listdir("/proc/self/fd"))) + 1)  # nothing else of ours
        os.chdir(request["workdir"])
        os.environ.clear()
        os.environ.update(request["env"])
        LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)  # the server dies: so do we
        if os.getppid() == server:  # (it did not die before the line above)
            code = run_sandbox(request["args"], server)
    except BaseException:
        import traceback

        traceback.print_exc()
    finally:
        sys.stderr.flush()
        os._exit(code)


# --------------------------------------------------------------------------- protocol


class Reader:
    """Buffered reads of the parent's requests into one buffer kept for the sandbox's life: a
    request written at once is read at once, with no allocation per read."""

    def __init__(self, fd: int, size: int = 65536):
        self.fd, self.buffer = fd, bytearray(size)
        self.view = memoryview(self.buffer)
        self.start = self.end = 0  # the unread bytes: buffer[start:end]

    def fill(self, size: int) -> bool:
        """At least `size` unread bytes from buffer[start] (False at the end of input)."""
        if self.end - self.start >= size:
            return True
        if self.start + size > len(self.buffer):  # move what is unread to the front, growing if need be
            unread = bytes(self.view[self.start:self.end])
            if size > len(self.buffer):
                self.buffer = bytearray(size)
                self.view = memoryview(self.buffer)
            self.buffer[:len(unread)] = unread
            self.start, self.end = 0, len(unread)
        while self.end - self.start < size:
            got = os.readv(self.fd, [self.view[self.end:]])
            if not got:
                return False
            self.end += got
        return True

    def consume(self, size: int) -> None:
        self.start += size
        if self.start == self.end:
            self.start = self.end = 0

    def read_exact(self, size: int) -> bytes:
        """`size` bytes, or b"" at the end of input."""
        if not self.fill(size):
            return b""
        data = bytes(self.view[self.start:self.start + size])
        self.consume(size)
        return data


class Writer:
    """Action frames built in one buffer kept for the sandbox's life and sent with one write."""

    AT = 3  # the frame starts here, so that its floats (after 9 bytes of header) are aligned

    def __init__(self, fd: int, rows: int = MAX_BATCH):
        import numpy as np

        self.fd, self.buffer = fd, bytearray(self.AT + HEADER.size + 8 * rows)
        self.view = memoryview(self.buffer)
        self.floats = np.frombuffer(self.buffer, dtype="<f4", offset=self.AT + HEADER.size)

    def actions(self, actions) -> None:
        n, d = actions.shape
        HEADER.pack_into(self.buffer, self.AT, b"A", n, d)
        self.floats[:n * d] = actions.reshape(-1)
        send(self.fd, self.view[self.AT:self.AT + HEADER.size + 4 * n * d])


def send(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def send_text(fd: int, tag: bytes, text: str) -> None:
    payload = text.encode("utf-8", errors="replace")[:65536]
    send(fd, tag + LENGTH.pack(len(payload)) + payload)


def serve(agent, proto_in: int, proto_out: int, memory_mb: int) -> None:
    import numpy as np

    from league.validation.loading import failure_reason

    requests, answers = Reader(proto_in), Writer(proto_out)
    while True:
        if not requests.fill(HEADER.size):
            return
        tag, n, d = HEADER.unpack_from(requests.buffer, requests.start)
        if tag != b"I" or n > MAX_BATCH or d != agent.obs_dim:
            send_text(proto_out, b"E", f"sandbox protocol error: request {tag!r} {n}x{d}")
            return
        size = HEADER.size + 4 * n * d
        if not requests.fill(size):
            return
        # the model's own copy, writable (as a fresh array of the environment's would be)
        obs = np.frombuffer(requests.buffer, dtype="<f4", count=n * d,
                            offset=requests.start + HEADER.size).reshape(n, d).copy()
        requests.consume(size)
        try:
            actions = np.ascontiguousarray(agent(obs), dtype="<f4")
        except Exception as error:  # the model's failure is an answer, not the sandbox's end
            send_text(proto_out, b"E", failure_reason(error, memory_mb))
            continue
        if actions.ndim != 2 or actions.shape[0] > MAX_BATCH or actions.shape[1] != 2:  # (the agent checks them)
            send_text(proto_out, b"E", f"the model's output has shape {actions.shape}")
            continue
        answers.actions(actions)


def main(argv: list[str]) -> int:
    # This tree's package, whether or not it is installed (python -P keeps the script's own folder,
    # the sandbox's, off the path; a worker may run from a checkout).
    if str(LEAGUE_DIR.parent) not in sys.path:
        sys.path.insert(0, str(LEAGUE_DIR.parent))
    if argv[1:2] == ["--fork-server"]:  # --fork-server FD RUNTIME [--prepare-when-idle]
        return fork_server(int(argv[2]), argv[3], prepare_when_idle="--prepare-when-idle" in argv[4:])
    return run_sandbox(argv[1:], os.getppid())


def run_sandbox(args: list[str], server: int) -> int:
    """Serve one model: MODEL MEMORY_MB CPU_S UID_BASE, the protocol on stdin/stdout; `server` is the
    process it must not outlive. With MODEL "--probe", confine, run the tiny model of the runtime
    its server prepared and report how the sandbox is isolated."""
    from league.validation.loading import failure_reason

    model, memory_mb, cpu_seconds, uid_base = args[0], int(args[1]), int(args[2]), int(args[3])
    proto_in, proto_out = take_protocol_fds()
    try:
        isolation = confine(cpu_seconds, uid_base, server)
        if model == "--probe":
            isolation.update(probe_runtimes())
        agent = None if model == "--probe" else load_model(Path(model), memory_mb)
    except BaseException as error:  # whatever the file did, it is the reason it is refused
        send_text(proto_out, b"E", failure_reason(error, memory_mb))
        return 1
    send_text(proto_out, b"R", json.dumps({"isolation": isolation, "obs_dim": getattr(agent, "obs_dim", None)}))
    if agent is not None:
        serve(agent, proto_in, proto_out, memory_mb)
    return 0


def confine(cpu_seconds: int, uid_base: int, server: int) -> dict:
    """Everything the sandbox does to itself before it reads the model, in this order: limits, its own
    network namespace, its own user, the parent-death signal, no new privileges, Landlock, seccomp."""
    limit_resources(cpu_seconds)
    # root without CAP_SYS_ADMIN (a container) enters a user namespace only once it left root: entered
    # as root, the sandbox would keep root's user id outside it instead of taking its own
    network = isolate_network(user_namespace=os.geteuid() != 0)
    ruleset, landlock_abi = files_ruleset()  # (before it leaves root)
    user = become_sandbox_user(uid_base)
    if network == "unavailable":
        network = isolate_network()
    die_with_the_server(server)
    restrict_files(ruleset)
    restrict_syscalls()
    single_thread_environment()
    return {"network": network, "user": user, "landlock": landlock_abi, "seccomp": True}


def probe_runtimes() -> dict:
    """Under the sandbox's confinement, load and run the tiny model of the runtime its server
    prepared (does this install let sandboxes load models?), and say whether the sandbox's user can
    read its runtime's files or uses them as its server loaded them."""
    for suffix, data in PREPARED.items():
        path = Path(f"probe{suffix}")
        path.write_bytes(data)
        run_tiny_model(path)
    modules = [sys.modules[name] for name in ("os", "numpy", "onnxruntime", "torch") if name in sys.modules]
    readable = all(os.access(module.__file__, os.R_OK) for module in modules)
    from league.constants import MODEL_SUFFIXES as kinds
    return {"runtimes": sorted(kinds[suffix] for suffix in PREPARED),
            "runtime": "readable" if readable else "preloaded"}


if __name__ == "__main__":
    sys.exit(main(sys.argv))

"""A league as most instructors run it: an ordinary user (not root) runs `league serve` from a
virtual environment of their own.

The user is created once (`ordinary_user`). The venv is made from the system's Python (the only
Python every user can run here: a pyenv under /root is not) and given this environment's packages
as hard links (the same files a pip install writes, in seconds); `OrdinaryLeague` installs a copy
of this checkout's league package into it, as pip would, and starts the server as that user with
the open-file limits given (the issue's server had 1,024 handles), its files in a home of its own.
Needs root to create the user and to start the server as them; skipped with the reason otherwise.
"""
from __future__ import annotations

import contextlib
import os
import pwd
import shutil
import socket
import subprocess
import sysconfig
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import pytest

from ..layout import REPO

USER = "league-test"
SYSTEM_PYTHON = Path("/usr/bin/python3")


def require_root_tools() -> None:
    if os.geteuid() != 0:
        pytest.skip("creating a user for the test needs root (run the suite as root, or this file as that user)")
    for tool in ("useradd", "runuser", "prlimit"):
        if shutil.which(tool) is None:
            pytest.skip(f"needs {tool} (Debian: passwd / util-linux)")
    if not SYSTEM_PYTHON.exists():
        pytest.skip("needs the system's Python (Debian: apt-get install python3 python3-venv)")


def ordinary_user() -> int:
    if subprocess.run(["id", "-u", USER], capture_output=True).returncode != 0:
        subprocess.run(["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin", USER], check=True)
    return int(subprocess.run(["id", "-u", USER], capture_output=True, text=True, check=True).stdout)


def environment_for_others(root: Path) -> Path:
    """A venv of the system's Python holding this environment's packages; returns its python.
    The packages are hard links to this environment's files: read them, never change their mode."""
    venv = root / "venv"
    subprocess.run([str(SYSTEM_PYTHON), "-m", "venv", "--without-pip", str(venv)], check=True)
    site = next(venv.glob("lib/python3*/site-packages"))
    ours = {Path(sysconfig.get_paths()[key]) for key in ("purelib", "platlib")}
    for packages in ours:
        for entry in packages.iterdir():
            if entry.name.startswith("__editable__") or entry.name.endswith(".pth"):
                continue  # the league package is copied, never pointed at through a .pth
            target = site / entry.name
            if not target.exists():
                subprocess.run(["cp", "-al", str(entry), str(target)], check=True)
    return venv / "bin" / "python"


def readable_copy(source: Path, target: Path) -> None:
    """A copy of `source` that every user may read (never the venv's packages: links to ours)."""
    shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for path in [target, *target.rglob("*")]:
        os.chmod(path, 0o755 if path.is_dir() or path.suffix == ".so" else 0o644)


@contextlib.contextmanager
def shared_directory():
    """A directory other users may enter (pytest's own temporary directories are its user's alone)."""
    path = Path(tempfile.mkdtemp(prefix="league-ordinary-"))
    os.chmod(path, 0o755)
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


@dataclass
class OrdinaryLeague:
    """`python -m league serve --no-worker` run by USER from a venv under `root`, on SQLite in USER's
    home there. `settings` are LEAGUE_* variables; `open_files` the (soft, hard) limit it starts with."""

    root: Path
    host: str = "127.0.0.1"
    port: int = 0
    settings: dict[str, str] = field(default_factory=dict)
    open_files: tuple[int, int] = (1024, 4096)
    api: subprocess.Popen | None = None

    def __post_init__(self):
        require_root_tools()
        self.uid = ordinary_user()
        self.python = environment_for_others(self.root)
        readable_copy(REPO / "league", Path(next(self.root.glob("venv/lib/python3*/site-packages"))) / "league")
        self.home = self.root / "home"
        self.home.mkdir()
        os.chown(self.home, self.uid, pwd.getpwuid(self.uid).pw_gid)

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    @property
    def log(self) -> str:
        path = self.home / "api.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def start(self) -> None:
        self.port = self.port or free_port(self.host)
        env = {"PATH": os.defpath, "HOME": str(self.home), "LANG": "C.UTF-8", "TMPDIR": str(self.home),
               "LEAGUE_DATA_DIR": str(self.home / "data"), "LEAGUE_BASELINES_DIR": str(self.home / "baselines"),
               "LEAGUE_CPU_SLOTS_DIR": str(self.home / "cpu-slots"),
               **self.settings}
        soft, hard = self.open_files
        command = ["prlimit", f"--nofile={soft}:{hard}", "--", str(self.python), "-m", "league", "serve",
                   "--no-worker", "--host", self.host, "--port", str(self.port)]
        gid = pwd.getpwuid(self.uid).pw_gid
        with open(self.home / "api.log", "ab") as log:  # prlimit execs the server: the same pid
            self.api = subprocess.Popen(command, env=env, cwd=self.home, stdout=log, stderr=subprocess.STDOUT,
                                        user=self.uid, group=gid, extra_groups=[])
        self.wait_healthy()

    def wait_healthy(self, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.api.poll() is not None:
                raise RuntimeError(f"the server exited ({self.api.returncode}):\n{self.log[-4000:]}")
            with contextlib.suppress(httpx.HTTPError, ValueError, KeyError):  # "degraded": --no-worker, it answers
                if httpx.get(f"{self.url}/api/health", timeout=2).json()["status"] in ("ok", "degraded"):
                    return
            time.sleep(0.2)
        raise TimeoutError(f"the server did not answer in {timeout} s:\n{self.log[-4000:]}")

    def status(self, field_name: str) -> str:
        """A line of /proc/PID/status of the server, e.g. status("VmRSS") -> "123456 kB"."""
        for line in Path(f"/proc/{self.api.pid}/status").read_text().splitlines():
            if line.startswith(field_name + ":"):
                return line.split(":", 1)[1].strip()
        raise KeyError(field_name)

    def open_files_now(self) -> tuple[int, int]:
        """The server's (soft, hard) limit of open files, as /proc/PID/limits says."""
        line = next(line for line in Path(f"/proc/{self.api.pid}/limits").read_text().splitlines()
                    if line.startswith("Max open files"))
        soft, hard = line.split()[3:5]
        return int(soft), int(hard)

    def rss_mb(self) -> float:
        return int(self.status("VmRSS").split()[0]) / 1024

    def stop(self) -> None:
        if self.api is not None and self.api.poll() is None:
            self.api.terminate()
            try:
                self.api.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.api.kill()
                self.api.wait()


def free_port(host: str) -> int:
    with socket.socket() as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]

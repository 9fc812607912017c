"""The sandbox tests again, as an ordinary user: how most instructors run the server.

The test creates a user and a virtual environment under /tmp from the system's Python (the only
Python every user can run here: a pyenv under /root is not), gives it this environment's packages
(hard links: the same files a pip install writes, in seconds) and a copy of the league package and
the tests, and runs tests/server/sandbox there with `runuser`. Isolation must hold without root:
Landlock, seccomp and a network namespace of an unprivileged user namespace.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sysconfig
import tempfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a second pytest run, in another environment

REPO = Path(__file__).resolve().parents[3]
USER = "league-test"
SYSTEM_PYTHON = Path("/usr/bin/python3")


def require_root_tools() -> None:
    if os.geteuid() != 0:
        pytest.skip("creating a user for the test needs root (run the suite as root, or this file as that user)")
    for tool in ("useradd", "runuser"):
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
                continue  # the league package is copied below, never pointed at through a .pth
            target = site / entry.name
            if not target.exists():
                subprocess.run(["cp", "-al", str(entry), str(target)], check=True)
    return venv / "bin" / "python"


@pytest.fixture
def shared_tmp():
    """A directory other users may enter (pytest's own temporary directories are its user's alone)."""
    path = Path(tempfile.mkdtemp(prefix="league-unprivileged-"))
    os.chmod(path, 0o755)
    yield path
    shutil.rmtree(path, ignore_errors=True)


@pytest.mark.long
def test_the_sandbox_tests_pass_as_an_ordinary_user(shared_tmp):
    require_root_tools()
    uid = ordinary_user()
    root = shared_tmp
    python = environment_for_others(root)
    source = root / "src"
    shutil.copytree(REPO / "league", source / "league", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO / "tests", source / "tests", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    shutil.copy(REPO / "pyproject.toml", source)  # the markers and test settings
    for path in [source, *source.rglob("*")]:  # copies: never the venv, whose files are links to ours
        os.chmod(path, 0o755 if path.is_dir() else 0o644)
    home = root / "home"
    home.mkdir()
    os.chown(home, uid, uid)
    env = {"PATH": os.defpath, "HOME": str(home), "PYTHONPATH": str(source), "LANG": "C.UTF-8",
           "TMPDIR": str(home)}
    result = subprocess.run([shutil.which("runuser"), "-u", USER, "--", str(python), "-m", "pytest", "-p", "no:cacheprovider",
                             "-q", "-rs", "-m", "not slow", "tests/server/sandbox"], cwd=source, env=env,
                            capture_output=True, text=True, timeout=900)
    summary = result.stdout.strip().splitlines()[-1] if result.stdout.strip() else ""
    assert result.returncode == 0, result.stdout[-6000:] + result.stderr[-2000:]
    assert " passed" in summary and "skipped" not in summary, result.stdout[-3000:]

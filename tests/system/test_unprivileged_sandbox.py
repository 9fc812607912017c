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

import pytest

from ..layout import REPO
from .ordinary import USER, environment_for_others, ordinary_user, require_root_tools, shared_directory




@pytest.fixture
def shared_tmp():
    with shared_directory() as path:
        yield path


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
    result = subprocess.run([shutil.which("runuser"), "-u", USER, "--", str(python), "-m", "pytest",
                             "-p", "no:cacheprovider", "-q", "-rs", "-m", "not slow", "tests/server/sandbox"],
                            cwd=source, env=env,
                            capture_output=True, text=True, timeout=900)
    summary = result.stdout.strip().splitlines()[-1] if result.stdout.strip() else ""
    assert result.returncode == 0, result.stdout[-6000:] + result.stderr[-2000:]
    assert " passed" in summary and "skipped" not in summary, result.stdout[-3000:]

"""A course's first hour exactly as the README documents it, by an ordinary user (not root), in fresh
virtual environments that hold only the documented extras (no test extra, no Cython but the one the
server extra brings):

- the README's two commands, verbatim, in a copy of this checkout (as a fresh clone), the torch
  line only swapped for `pip install "torch==2.13.0"` (this machine reaches PyTorch's CPU index
  through a local wheel directory only, PIP_FIND_LINKS, passed on so that torch stays the CPU build);
- the instructor's own commands from that install: `league login`, `league assignments`, `league grades`;
- a student's venv installs the server's sdist from GET /api/package (the file students whose
  machine is not like the server's take, built by the server from its own install), then runs
  `league check` and `league submit --wait`, and sees the result ready.

The server listens where the README says, 127.0.0.1:8000.
"""
from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import shlex
import signal
import socket
import subprocess
import time
from pathlib import Path

import httpx
import pytest

from ..layout import REPO
from .ordinary import require_root_tools, shared_directory
from .students import PIP_CACHE, Student, export

URL = "http://127.0.0.1:8000"  # where the README's `league serve` listens
TORCH_LINE = "pip install torch --index-url https://download.pytorch.org/whl/cpu"
TORCH_HERE = 'pip install "torch==2.13.0"'  # from PIP_FIND_LINKS, the release the test command installs
TOKEN = re.compile(r"lg_\S+")  # a line that is a token alone (league/server/core/security.py's prefix)
# Only to keep the test short: the baselines' and the student's evaluations, 3 episodes each.
SETTINGS = {"LEAGUE_EVAL_EPISODES": "3"}


def two_commands() -> str:
    """The README's block under "Two commands", with the torch line swapped as this machine needs."""
    section = (REPO / "README.md").read_text().split("## Two commands", 1)[1]
    block = re.search(r"^```bash\n(.*?)^```", section, re.S | re.M)[1]
    assert block.count(TORCH_LINE) == 1, block
    return block.replace(TORCH_LINE, TORCH_HERE)


def fresh_clone(target: Path, uid: int, gid: int) -> None:
    """The checkout's files as `git clone` gives them (tracked or new, not ignored), owned by the user."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=REPO,
                            capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = REPO / name
        if source.is_file() and not source.is_symlink():
            copy = target / name
            copy.parent.mkdir(parents=True, exist_ok=True)
            copy.write_bytes(source.read_bytes())
            copy.chmod(source.stat().st_mode & 0o777)
    for path in [target, *target.rglob("*")]:
        os.chown(path, uid, gid)


def port_in_use(port: int = 8000) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


def wait_healthy(server: subprocess.Popen, log: Path, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise AssertionError(f"the README's commands exited ({server.returncode}):\n{log.read_text()[-6000:]}")
        with contextlib.suppress(httpx.HTTPError):
            if httpx.get(f"{URL}/api/health", timeout=2).status_code == 200:
                return
        time.sleep(1)
    raise AssertionError(f"no server at {URL} after {timeout} s:\n{log.read_text()[-6000:]}")


@pytest.fixture(scope="module")
def documented_course():
    """The README's two commands run by an ordinary user in a fresh clone; yields (instructor, token, clone)."""
    require_root_tools()
    if port_in_use():
        pytest.skip("port 8000, where the README's server listens, is taken on this machine")
    with shared_directory() as root:
        (root / "instructor").mkdir()
        instructor = Student(root / "instructor")
        clone = instructor.home / "microracer-league"
        fresh_clone(clone, instructor.uid, instructor.gid)
        instructor.venv = clone / ".venv"  # the README's
        env = {"PATH": os.defpath, "HOME": str(instructor.home), "LANG": "C.UTF-8", "TMPDIR": str(instructor.home),
               "PIP_CACHE_DIR": str(PIP_CACHE), "PIP_FIND_LINKS": os.environ.get("PIP_FIND_LINKS", ""),
               **SETTINGS}
        log, out = instructor.home / "commands.log", instructor.home / "commands.out"
        with open(out, "wb") as stdout, open(log, "wb") as stderr:
            server = subprocess.Popen(["bash", "-euo", "pipefail", "-c", two_commands()], cwd=clone, env=env,
                                      stdout=stdout, stderr=stderr, user=instructor.uid, group=instructor.gid,
                                      extra_groups=[], start_new_session=True)
        try:
            wait_healthy(server, log, timeout=1800)
            tokens = [line for line in out.read_text().splitlines() if TOKEN.fullmatch(line)]
            assert len(tokens) == 1, out.read_text()[-3000:]  # league init --instructor prof's
            yield instructor, tokens[0], clone
        finally:
            stop_group(server)


def stop_group(server: subprocess.Popen, timeout: float = 60) -> None:
    """bash and what it started (`league serve`, which stops its worker): terminated, waited for
    until none is left in the group (port 8000 free again), killed after `timeout`."""
    os.killpg(server.pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        server.poll()  # reaps bash, which would otherwise stay in the group
        try:
            os.killpg(server.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.5)
    os.killpg(server.pid, signal.SIGKILL)
    server.wait()


@pytest.mark.long
def test_a_course_installed_as_the_readme_says_hands_students_its_package_and_takes_their_agents(
        documented_course, tmp_path):
    instructor, token, clone = documented_course
    installed = json.loads(instructor.run("pip", "list", "--format=json").stdout)
    names = {package["name"].lower() for package in installed}
    assert "pytest" not in names and "cython" in names  # the documented extras only: Cython is the server's
    assert not [name for name in names if name.startswith("nvidia")]

    # the instructor's own commands, from the same install
    login = instructor.run("league", "login", "--server", URL, "--token", token)
    assert "prof" in login.stdout + login.stderr
    instructor.run("league", "assignments", "create", "Sprint", "--due", "2099-01-01T00:00")
    assert "Sprint" in instructor.run("league", "assignments").stdout
    student_token = instructor.run("bash", "-c", f"cd {clone} && league users add ann").stdout.strip()
    assert TOKEN.fullmatch(student_token)

    # the server's package: the wheel and the sdist, built from the documented install
    package = httpx.get(f"{URL}/api/package", timeout=600)
    assert package.status_code == 200, package.text
    kinds = {file["kind"]: file for file in package.json()["files"]}
    assert set(kinds) == {"wheel", "sdist"}, kinds

    with shared_directory() as root:
        student = Student(root)
        student.run(str(Path("/usr/bin/python3")), "-m", "venv", str(student.venv))
        command = shlex.split(kinds["sdist"]["install"])
        assert command[:2] == ["pip", "install"] and command[2].startswith("microracer-league[onnx,client] @ http")
        student.run(*command, "-q")
        names = {p["name"].lower() for p in json.loads(student.run("pip", "list", "--format=json").stdout)}
        assert "pytest" not in names and not [name for name in names if name.startswith(("torch", "nvidia"))]
        model = student.give(export("onnx", tmp_path))
        checked = student.run("league", "check", model.name, "--server", URL)
        assert checked.stdout.startswith("policy.onnx: the server would accept it"), checked.stdout
        submitted = student.run("league", "submit", model.name, "--wait", "--no-progress", "--server", URL,
                                "--token", student_token, "--assignment", "Sprint")
        assert submitted.stdout.splitlines()[0].endswith(" is ready"), submitted.stdout

    rubric = instructor.home / "rubric.json"  # the server README's first example (Grades)
    rubric.write_text(json.dumps({"kind": "formula", "max_points": 10, "formula": "10 * completed"}))
    os.chown(rubric, instructor.uid, instructor.gid)
    instructor.run("league", "grades", "Sprint", "--set-rubric", rubric.name)
    grades = instructor.run("league", "grades", "Sprint").stdout
    statuses = {row["name"]: row["status"] for row in csv.DictReader(io.StringIO(grades))}
    assert statuses["ann"] == "open", grades  # her final is frozen at the due time, in 2099

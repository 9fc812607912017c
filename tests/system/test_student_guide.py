"""docs/STUDENT_GUIDE.md runs: its python and bash blocks, in order, in one folder, each pasted into
a file of its own and run as a script (`python block_3.py`), as a student runs them (the `league`
command, a real league server started here), with training at smoke size (GUIDE_STEPS). A block
that fails fails the test with its output."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from ..server.backends import fresh_backend
from ..server.commands import REPO
from .servers import baseline_submission, make_server

GUIDE = REPO / "docs" / "STUDENT_GUIDE.md"
BLOCK = re.compile(r"^```(python|bash)\n(.*?)^```", re.S | re.M)


def guide_blocks() -> list[tuple[str, str]]:
    return [(match.group(1), match.group(2)) for match in BLOCK.finditer(GUIDE.read_text())]


def test_the_guide_has_blocks_of_both_kinds():
    kinds = [kind for kind, _ in guide_blocks()]
    assert kinds.count("python") >= 5 and kinds.count("bash") >= 3


@pytest.mark.long
def test_every_block_of_the_student_guide_runs(tmp_path):
    pytest.importorskip("stable_baselines3", reason="the guide trains with Stable-Baselines3 (the rl extra)")
    with fresh_backend("sqlite", tmp_path) as database_url:
        server = make_server(tmp_path, database_url)
        server.start_api()
        try:
            with server.client(server.instructor_token) as instructor:
                token = instructor.post("/api/users", json={"name": "guide-student"}).json()["token"]
            work = tmp_path / "student"
            work.mkdir()
            base = {k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")}
            env = {**base, "PYTHONPATH": str(REPO), "XDG_CONFIG_HOME": str(tmp_path / "config"),
                   "PATH": os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"], "MPLBACKEND": "agg",
                   "GUIDE_STEPS": "512", "LEAGUE_SERVER": server.url, "LEAGUE_TOKEN": token,
                   "OPPONENT": str(baseline_submission(server)["id"])}
            for number, (kind, code) in enumerate(guide_blocks()):
                if '--assignment "time trial"' in code:  # the instructor opened a second assignment meanwhile
                    with server.client(server.instructor_token) as instructor:
                        instructor.post("/api/assignments",
                                        json={"name": "time trial", "episodes": 3}).raise_for_status()
                if "$MY_SUBMISSION" in code:  # the id of the upload a block before made
                    with server.client(token) as student:
                        env["MY_SUBMISSION"] = str(student.get("/api/submissions").json()[0]["id"])
                script = work / f"block_{number}.{'py' if kind == 'python' else 'sh'}"  # pasted into a file
                script.write_text(code)
                command = [sys.executable, script.name] if kind == "python" else ["bash", "-euo", "pipefail",
                                                                                  script.name]
                done = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True, timeout=600)
                assert done.returncode == 0, f"block {number} ({kind}) failed:\n{code}\n{done.stdout}\n{done.stderr}"
            assert (work / "race.mp4").stat().st_size > 10_000
        finally:
            server.stop_all()

"""docs/RL_LIBRARIES.md as a reader uses it: every Python block pasted into a file of its own and run
as a script (`python block.py`: torchrl's and Gymnasium's worker processes import that file again,
which `python -c` would hide), training at smoke size (GUIDE_STEPS); every bash block names what
exists: the extras it installs are the package's, the example scripts it runs take its options (the
scripts themselves run at smoke size in tests/test_rl_libraries.py). docs/STUDENT_GUIDE.md's blocks
run as files against a real server: tests/system/test_student_guide.py."""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tomllib

import pytest

from .layout import REPO

RL_LIBRARIES = REPO / "docs" / "RL_LIBRARIES.md"
BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)


def blocks(kind: str) -> list[str]:
    return [code for language, code in BLOCK.findall(RL_LIBRARIES.read_text()) if language == kind]


def test_the_page_has_python_and_bash_blocks():
    assert len(blocks("python")) >= 4 and len(blocks("bash")) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("number", range(len(blocks("python"))))
def test_every_python_block_runs_as_a_script_of_its_own(tmp_path, number):
    pytest.importorskip("torchrl", reason="the page's blocks use the rl extra")
    script = tmp_path / f"block_{number}.py"
    script.write_text(blocks("python")[number])
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")}, "MPLBACKEND": "agg",
           "GUIDE_STEPS": "512", "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, script.name], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, f"{script.read_text()}\n{done.stdout}\n{done.stderr[-4000:]}"


def test_every_bash_block_installs_the_packages_extras_and_runs_the_examples_options():
    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for line in (line for code in blocks("bash") for line in code.splitlines() if line.strip()):
        words = shlex.split(line, comments=True)
        if words[:2] == ["pip", "install"]:
            for requirement in words[2:]:
                name, _, extra = requirement.partition("[")
                if name == "microracer-league":
                    assert set(extra.rstrip("]").split(",")) <= set(extras), line
        else:
            assert words[0] == "python" and words[1].startswith("examples/"), line
            helped = subprocess.run([sys.executable, str(REPO / words[1]), "--help"], capture_output=True,
                                    text=True, timeout=300)
            assert helped.returncode == 0, helped.stderr
            assert all(option in helped.stdout for option in words[2:] if option.startswith("--")), line

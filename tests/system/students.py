"""The `league` command as a student runs it against the system tests' servers: its own config
directory and environment (test_client.py, test_student_install.py); a student's model exported
as torch's exporters write it, and an ordinary user with a venv of their own (test_student_install.py,
test_as_documented.py)."""
from __future__ import annotations

import os
import pwd
import subprocess
import sys
import warnings
from pathlib import Path

from ..server.commands import REPO
from .ordinary import ordinary_user

PIP_CACHE = Path("/tmp/league-student-pip-cache")  # the ordinary user's downloads, kept between runs


def league(*args: str, config, **env: str) -> subprocess.CompletedProcess:
    """`league ARGS` as a student runs it: its own config directory, no LEAGUE_* server settings
    but the ones given."""
    return subprocess.run([sys.executable, "-m", "league.cli", *args], cwd=config, env=student_env(config, **env),
                          capture_output=True, text=True, timeout=300)


def student_env(config, **env: str) -> dict:
    base = {k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")}
    return {**base, "XDG_CONFIG_HOME": str(config), "PYTHONPATH": str(REPO), **env}


def export(how: str, folder: Path) -> Path:
    """The thesis-like driver exported as a student would, with each exporter's defaults."""
    import torch

    from league.testing import thesis_driver

    model, example = thesis_driver().eval(), (torch.zeros(1, 5),)
    path = folder / ("policy.pt" if how.startswith("jit") else "policy.onnx")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter's and torch.jit's deprecation notices
        if how == "onnx":
            torch.onnx.export(model, example, str(path))
        elif how == "onnx-legacy":
            torch.onnx.export(model, example, str(path), dynamo=False)
        elif how == "jit-script":
            torch.jit.script(model).save(str(path))
        else:
            torch.jit.trace(model, example).save(str(path))
    return path


class Student:
    """An ordinary user with a home and a venv of the system's Python, under a shared directory."""

    def __init__(self, root: Path):
        self.uid = ordinary_user()
        self.gid = pwd.getpwuid(self.uid).pw_gid
        self.root, self.home, self.venv = root, root / "home", root / "home" / "venv"
        self.home.mkdir()
        PIP_CACHE.mkdir(exist_ok=True)
        for path in (self.home, PIP_CACHE):
            os.chown(path, self.uid, self.gid)

    def run(self, *command: str, expect: int | None = 0, **env: str) -> subprocess.CompletedProcess:
        base = {"PATH": f"{self.venv / 'bin'}:{os.defpath}", "HOME": str(self.home), "LANG": "C.UTF-8",
                "XDG_CONFIG_HOME": str(self.home / ".config"), "PIP_CACHE_DIR": str(PIP_CACHE),
                "PIP_FIND_LINKS": os.environ.get("PIP_FIND_LINKS", ""), "MPLBACKEND": "Agg"}
        done = subprocess.run(command, cwd=self.home, env={**base, **env}, capture_output=True, text=True,
                              timeout=900, user=self.uid, group=self.gid, extra_groups=[])
        if expect is not None:
            assert done.returncode == expect, f"{command}: {done.returncode}\n{done.stdout}\n{done.stderr}"
        return done

    def give(self, path: Path) -> Path:
        """A copy of a file (and what lies beside it under the same stem) that the student owns."""
        target = self.home / path.name
        for source in path.parent.glob(f"{path.name}*"):
            copy = self.home / source.name
            copy.write_bytes(source.read_bytes())
            os.chown(copy, self.uid, self.gid)
        return target

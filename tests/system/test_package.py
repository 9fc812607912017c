"""The league as a user installs it: a wheel in a fresh venv, `league serve` started in a folder that
is not the checkout, its pages and the baselines bundled with the package served, and that wheel's
files handed out to students (GET /api/package)."""
from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import httpx
import pytest

from ..layout import REPO
from ..server.api_calls import wait_for
from ..server.backends import TEST_SETTINGS
from .servers import LeagueServer

BUNDLED = sorted(p.stem for p in (REPO / "league" / "baselines" / "agents").glob("*.onnx"))


def outside_env() -> dict[str, str]:
    """This environment without the checkout on the path and without LEAGUE_ settings."""
    return {key: value for key, value in os.environ.items() if not key.startswith("LEAGUE_") and key != "PYTHONPATH"}


def run(*command, **kwargs) -> subprocess.CompletedProcess:
    kwargs.setdefault("env", outside_env())
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, **kwargs)
    assert done.returncode == 0, f"{command}: {done.stdout}\n{done.stderr}"
    return done


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """A venv with the wheel of this checkout installed (no dependencies: those of this interpreter,
    which may itself be a venv, are made visible through a .pth file, so nothing is downloaded).

    The wheel is built with this interpreter's setuptools, Cython and numpy (--no-build-isolation:
    the same wheel, file for file, without the 30 s of an isolated build environment); pip's
    isolated build from pyproject.toml's build requirements runs in test_as_documented.py, in the
    README's `pip install -e` and in the student's install of the server's sdist."""
    tmp = tmp_path_factory.mktemp("package")
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp / "dist"),
        str(REPO), cwd=tmp)
    wheel = next((tmp / "dist").glob("microracer_league-*.whl"))
    venv = tmp / "venv"
    run(sys.executable, "-m", "venv", "--system-site-packages", str(venv))
    python = venv / "bin" / "python"
    run(str(python), "-m", "pip", "install", "--no-deps", "--no-index", "-q", str(wheel))
    site = Path(run(str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    # after the install (pip would take this checkout's editable install for it); a plain path: the
    # .pth files there (that editable install's) are not read
    (site / "_parent_environment.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv


def package_files(wheel: bytes) -> dict[str, bytes]:
    """The package's files in a wheel (not its dist-info, which the installer rewrites)."""
    with zipfile.ZipFile(io.BytesIO(wheel)) as archive:
        return {name: archive.read(name) for name in archive.namelist() if name.startswith("league/")}


@pytest.mark.long
def test_an_installed_server_started_elsewhere_registers_the_bundled_baselines(installed, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = outside_env()
    env.update(TEST_SETTINGS, LEAGUE_EVAL_EPISODES="1", LEAGUE_DATA_DIR=str(elsewhere / "data"),
               LEAGUE_CPU_SLOTS_DIR=str(tmp_path / "cpu-slots"),
               LEAGUE_BOARD_VISIBILITY="public",  # the board is read below as a visitor, with no account
               # the dependencies come through a .pth path, which sandboxes may not read (by design,
               # sandbox/child.py read_roots): here they run without Landlock
               LEAGUE_SANDBOX_REQUIRE_ISOLATION="false")
    where = run(str(installed / "bin" / "python"), "-c", "import league.server.core.config as c; "
                "print(c.__file__); print(c.Settings().resolved_baselines_dir)", env=env, cwd=elsewhere).stdout
    module, baselines_dir = where.split()
    assert Path(module).is_relative_to(installed) and Path(baselines_dir).is_relative_to(installed)

    server = LeagueServer(env, tmp_path)
    server.api = subprocess.Popen([str(installed / "bin" / "league"), "serve", "--port", str(server.port)], env=env,
                                  cwd=elsewhere, stdout=open(tmp_path / "api.log", "wb"), stderr=subprocess.STDOUT)
    try:
        server.wait_healthy()
        # the pages are package data: served from the installation, not from the working directory
        page = httpx.get(f"{server.url}/", timeout=10)
        assert page.status_code == 200 and "<main" in page.text, page.text[:500]
        assert httpx.get(f"{server.url}/static/js/api.js", timeout=10).status_code == 200

        def baselines_on_the_board() -> list[str]:
            rows = httpx.get(f"{server.url}/api/leaderboard", params={"size": 100}, timeout=10).json()["items"]
            return sorted(row["name"] for row in rows if row["owner"] == "baselines")

        assert wait_for(baselines_on_the_board, lambda names: names == BUNDLED, timeout=240, interval=1) == BUNDLED
        served = httpx.get(f"{server.url}/api/package", timeout=120).json()["files"]
        handed_out = httpx.get(served[0]["url"], timeout=60).content
    finally:
        server.stop(server.api)
    # installed from a wheel, the server hands out that wheel: the same files, rebuilt from its installation
    wheel = next((installed.parent / "dist").glob("microracer_league-*.whl"))
    assert [(file["kind"], file["filename"]) for file in served] == [("wheel", wheel.name)]
    assert package_files(handed_out) == package_files(wheel.read_bytes())
    assert len(BUNDLED) == 6 and all(json.loads((REPO / "league/baselines/agents" / f"{name}.json").read_text())
                                     for name in BUNDLED)  # each agent has its card
    assert not (elsewhere / "data" / "baselines").exists()

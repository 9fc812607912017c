"""System tests: the league as its users run it. Servers and workers as processes (killed, restarted,
upgraded, backed up), workers on other hosts (network namespaces), browsers, installs into fresh venvs
by ordinary users, the student guide run block by block, and the API's routes where they run jobs on
a `league serve` and its worker (tests/system/api/). All of them are the slow tier (tests/conftest.py).

The databases and settings (tests/server/backends.py), the fixtures `backend` and `models`
(tests/server/fixtures.py) and the HTTP helpers (tests/server/api_calls.py) are the server tests';
the servers and what the tests do with them are in servers.py, championship rounds in rounds.py, the
student's `league` command in students.py; the fixtures shared by several files of this folder are here.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from ..server.backends import BACKENDS
from .servers import running_server


@pytest.fixture(scope="package", params=BACKENDS)
def league_server(request, tmp_path_factory):
    """A running `league serve` (API + its worker process) per backend, shared by the API tests."""
    with running_server(tmp_path_factory.mktemp(f"league-{request.param}"), request.param) as server:
        yield server


@pytest.fixture(scope="module")
def sqlite_server(tmp_path_factory):
    """A running `league serve` on SQLite, shared by a module's tests (the student's toolkit against it)."""
    with running_server(tmp_path_factory.mktemp("client"), "sqlite") as server:
        yield server


@pytest.fixture(scope="module")
def drivers(tmp_path_factory) -> list[Path]:
    """Eight thesis-size ONNX drivers that all lap the track, each at a speed of its own."""
    from league.agents import export_onnx

    from league.testing import thesis_driver

    d = tmp_path_factory.mktemp("round-drivers")
    speeds = [0.20, 0.22, 0.24, 0.26, 0.28, 0.21, 0.23, 0.25]
    return [export_onnx(thesis_driver(target_speed=speed, seed=k), d / f"driver_{k}.onnx")
            for k, speed in enumerate(speeds)]

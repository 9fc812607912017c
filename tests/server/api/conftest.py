"""Fixtures of the API tests: the league in this process (in_process.py) they share, per backend."""
from __future__ import annotations

import pytest

from ..backends import BACKENDS
from .in_process import in_process_league


@pytest.fixture(scope="package", params=BACKENDS)
def app_league(request, tmp_path_factory):
    """The in-process league the API tests share, per backend."""
    with in_process_league(request.param, tmp_path_factory.mktemp(f"app-{request.param}")) as league:
        yield league

"""System tests: the league as its users run it. Servers and workers as processes (killed, restarted,
upgraded, backed up), workers on other hosts (network namespaces), browsers, installs into fresh venvs
by ordinary users, the student guide run block by block. All of them are the slow tier (tests/conftest.py).

The databases, settings, `LeagueServer` and HTTP helpers are the server tests' (tests/server/conftest.py):
the API route tests that run jobs start the same servers.
"""
from __future__ import annotations

from ..server.conftest import backend, models  # noqa: F401 - fixtures: a database of each backend, the model files

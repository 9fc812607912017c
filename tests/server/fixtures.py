"""Fixtures of the server and system tests: a database of each backend, and the model files the tests
upload. A pytest plugin (tests/conftest.py names it in `pytest_plugins`), so that both folders get them
by name from one definition: the model files are built once a session.

What the two folders share that is not a fixture: the databases and the test settings in
backends.py, the source tree and `python -m league.server` in commands.py, what the tests do with a
league over HTTP in api_calls.py.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from league import testing as mf

from .backends import BACKENDS, fresh_backend


@pytest.fixture(params=BACKENDS)
def backend(request, tmp_path):
    with fresh_backend(request.param, tmp_path) as database_url:
        yield request.param, database_url


@pytest.fixture(scope="session")
def models(tmp_path_factory) -> dict[str, Path]:
    """Every model file the tests upload, built once."""
    d = tmp_path_factory.mktemp("server-models")
    from league.agents import export_onnx, export_torchscript

    from league.testing import thesis_driver

    good_onnx = export_onnx(thesis_driver(), d / "thesis_actor.onnx")
    return {
        "onnx": good_onnx,
        "torchscript": export_torchscript(thesis_driver(), d / "thesis_actor.pt"),
        "heuristic_onnx": mf.onnx_heuristic(d / "heuristic.onnx"),
        "random_bytes": mf.random_bytes(d / "random.onnx"),
        "truncated": mf.truncated(good_onnx, d / "truncated.onnx"),
        "pickle_pt": mf.pickle_renamed_pt(d / "checkpoint.pt"),
        "wrong_input": mf.onnx_mlp(d / "input7.onnx", in_dim=7),
        "wrong_output": mf.onnx_mlp(d / "output3.onnx", out_dim=3),
        "nan": mf.onnx_mlp(d / "nan.onnx", nan=True),
        "loop": mf.torchscript_loop(d / "loop.pt"),
        "slow": mf.onnx_slow(d / "slow.onnx"),
        "memory_hog": mf.onnx_memory_hog(d / "hog.onnx"),
        "external_data": mf.onnx_external_data(d / "external.onnx"),
        "custom_domain": mf.onnx_custom_domain(d / "custom.onnx"),
        "reads_file": mf.torchscript_reads_file(d / "reads_file.pt"),
    }


"""Shared pytest fixtures."""
from __future__ import annotations

import pytest

# toolkit fixtures ------------------------------------------------------------------------
# A thesis-size actor (5 -> 64 -> 64 -> 2) exported once per session to ONNX and TorchScript,
# plus its lidar-size twin; see tests/toolkit_models.py.


@pytest.fixture(scope="session")
def thesis_module():
    pytest.importorskip("torch")
    from .toolkit_models import thesis_driver

    return thesis_driver()


@pytest.fixture(scope="session")
def models_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("models")


@pytest.fixture(scope="session")
def onnx_actor(thesis_module, models_dir):
    pytest.importorskip("onnxruntime")
    from league.agents import export_onnx

    return export_onnx(thesis_module, models_dir / "thesis_actor.onnx")


@pytest.fixture(scope="session")
def torchscript_actor(thesis_module, models_dir):
    from league.agents import export_torchscript

    return export_torchscript(thesis_module, models_dir / "thesis_actor.pt")


@pytest.fixture(scope="session")
def lidar_onnx_actor(models_dir):
    pytest.importorskip("onnxruntime")
    from league.agents import export_onnx

    from .toolkit_models import thesis_driver

    return export_onnx(thesis_driver(obs_dim=20), models_dir / "lidar_actor.onnx", obs_dim=20)

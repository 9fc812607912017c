"""Shared pytest fixtures, the two tiers and the order that starts the files of `long` tests first.

    python -m pytest -n 2 -m "not slow"   the quick loop: unit tests, in this process or in sandboxes
    python -m pytest -n 2 --dist loadfile --no-loadscope-reorder   the whole suite (what CI runs)
    python -m pytest -n 2 --dist loadfile --no-loadscope-reorder tests/system   the system tests alone

The slow tier: the folder tests/system/ (leagues of `league serve` and `league worker` processes,
hosts, browsers, installs), marked here by folder, and the tests marked `slow` (the baselines'
trainings). A test elsewhere that imports what starts those processes (tests/system/servers.py) is
a system test in the wrong folder: collection fails and says so. (Their fixtures, in
tests/system/conftest.py, are not even visible elsewhere.) Nor does a test module import another
test module: what two of them share goes in a helper module of their folder (tests/formulas.py,
tests/system/rounds.py, ...), and collection fails on such an import. Nor does any module of the
tests import from a conftest: conftests hold fixtures and hooks, which pytest gives by name; the
helpers they use live in helper modules (tests/server/backends.py, api_calls.py, ...). The checks
are in tests/layout.py.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from .layout import SERVERS, SYSTEM, imported_conftests, imported_test_modules, starts_servers

pytest_plugins = ["tests.server.fixtures"]  # a database of each backend, the model files: server and system tests


def pytest_collection_modifyitems(items):
    elsewhere = {item.path: getattr(item, "module", None) for item in items if SYSTEM not in item.path.parents}
    misplaced = sorted(str(path.relative_to(SYSTEM.parent.parent)) for path, module in elsewhere.items()
                       if starts_servers(module))
    if misplaced:
        raise pytest.UsageError(f"{', '.join(misplaced)}: a test outside tests/system uses {SERVERS} (leagues "
                                f"as processes): move it to tests/system/, or run the app in process "
                                f"(tests/server/api/in_process.py)")
    crossed = [f"{path.relative_to(SYSTEM.parent.parent)} imports {', '.join(names)}"
               for path in sorted({item.path for item in items}) if (names := imported_test_modules(path))]
    if crossed:
        raise pytest.UsageError(f"{'; '.join(crossed)}: a test module imports another test module: move what "
                                f"they share to a helper module of the folder (not test_*.py), or a conftest "
                                f"if it is a fixture")
    helpers = {Path(module.__file__) for name, module in list(sys.modules.items())
               if name.startswith("tests.") and not name.endswith("conftest") and getattr(module, "__file__", None)}
    importers = [f"{path.relative_to(SYSTEM.parent.parent)} imports {', '.join(names)}"
                 for path in sorted({item.path for item in items} | helpers) if (names := imported_conftests(path))]
    if importers:
        raise pytest.UsageError(f"{'; '.join(importers)}: a module of the tests imports from a conftest: a fixture "
                                f"needs no import (pytest gives it by name), and what is not a fixture goes in a "
                                f"helper module of the folder")
    for item in items:
        if item.path not in elsewhere:
            item.add_marker(pytest.mark.slow)
    # The files of `long` tests first: under `pytest -n 2 --dist loadfile --no-loadscope-reorder`
    # (the README's command; without the last option xdist sends the files with most tests first) a
    # file started last ends the run, and these take a minute or more each.
    long_files = {item.path for item in items if item.get_closest_marker("long")}
    items.sort(key=lambda item: item.path not in long_files)  # stable: the rest keep their order


# toolkit fixtures ------------------------------------------------------------------------
# A thesis-size actor (5 -> 64 -> 64 -> 2) exported once per session to ONNX and TorchScript,
# plus its lidar-size twin; see league/testing.py.


@pytest.fixture(scope="session")
def thesis_module():
    pytest.importorskip("torch")
    from league.testing import thesis_driver

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

    from league.testing import thesis_driver

    return export_onnx(thesis_driver(obs_dim=20), models_dir / "lidar_actor.onnx", obs_dim=20)

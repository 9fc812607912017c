"""The tests' layout that collection enforces (tests/conftest.py): system tests in tests/system, and
no test module importing another test module or a conftest."""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]  # the checkout the tests run from
SYSTEM = Path(__file__).parent / "system"
SERVERS = "tests.system.servers"  # the module that starts leagues as processes


def imported_test_modules(path: Path) -> list[str]:
    """What the file at `path` imports of this package's test modules (test_*.py): the modules, or
    names that start with test_ (a test module, or a test function, which would then run twice)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names
                      if alias.name.startswith("tests.") and alias.name.rsplit(".", 1)[-1].startswith("test_")]
        elif isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").split(".")[0] == "tests"):
            module = "." * node.level + (node.module or "")
            found += [module] if module.rsplit(".", 1)[-1].startswith("test_") else \
                [f"{alias.name} from {module}" for alias in node.names if alias.name.startswith("test_")]
    return found


def starts_servers(module) -> bool:
    """Whether a test module holds the module that starts leagues as processes, or anything of it."""
    return module is not None and any(
        getattr(value, "__module__", None) == SERVERS or getattr(value, "__name__", None) == SERVERS
        for value in vars(module).values())


def imported_conftests(path: Path) -> list[str]:
    """The conftest modules the file at `path` imports from (pytest gives their fixtures by name;
    what is not a fixture belongs in a helper module)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names if alias.name.rsplit(".", 1)[-1] == "conftest"]
        elif isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            found += [module] if (node.module or "").rsplit(".", 1)[-1] == "conftest" else \
                [f"{module}.conftest" for alias in node.names if alias.name == "conftest"]
    return found

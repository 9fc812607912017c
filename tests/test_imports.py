"""Imports go one way (STYLE.md): the toolkit never imports the server, and the baselines' shared
code never imports the package that lists the algorithms built on it. Every import of every module
of the package counts, those inside functions too (they run as soon as the function does)."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "league"
# The command line is where the toolkit and the server meet: it adds the server's commands when
# the server extra is installed (league/cli.py, _add_server_commands).
COMPOSITION = {("league.cli", "league.server.cli")}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path) -> set[str]:
    return imports_of(path.read_text(), module_name(path), path.name == "__init__.py")


def imports_of(source: str, name: str, is_package: bool = False) -> set[str]:
    """The league modules that the source of module `name` imports (for `from X import name`: X,
    and X.name where that is a module)."""
    package, found = name if is_package else name.rpartition(".")[0], set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            found.add(base)
            found |= {f"{base}.{alias.name}" for alias in node.names if _is_module(f"{base}.{alias.name}")}
    return {module for module in found if module == "league" or module.startswith("league.")}


def _is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def import_graph() -> dict[str, set[str]]:
    return {module_name(path): imports(path) for path in sorted(PACKAGE.rglob("*.py"))}


def upward(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """The edges that go the wrong way."""
    wrong = []
    for source, targets in graph.items():
        for target in targets:
            toolkit_to_server = not _in(source, "league.server") and _in(target, "league.server")
            common_to_registry = _in(source, "league.baselines.common") and _in(target, "league.baselines") \
                and not _in(target, "league.baselines.common")
            if (toolkit_to_server and (source, target) not in COMPOSITION) or common_to_registry:
                wrong.append((source, target))
    return sorted(wrong)


def _in(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def test_imports_go_one_way():
    graph = import_graph()
    assert len(graph) > 50 and graph["league.client"]  # the walk found the package
    assert upward(graph) == []


def test_the_walk_sees_what_would_be_an_upward_edge():
    """The rules catch the edges this change removed (the client's on the server's validation, the
    baselines' export on their registry), written as the old code wrote them, and relative ones."""
    graph = {
        "league.client": imports_of("def check():\n    from league.server.sandbox.validation import validate_model\n",
                                    "league.client"),
        "league.baselines.common.export": imports_of("from league.baselines import load_algorithm\n",
                                                     "league.baselines.common.export"),
        "league.validation.files": imports_of("from ..server import storage\n", "league.validation.files"),
    }
    assert upward(graph) == [("league.baselines.common.export", "league.baselines"),
                             ("league.client", "league.server.sandbox.validation"),
                             ("league.validation.files", "league.server"),
                             ("league.validation.files", "league.server.storage")]

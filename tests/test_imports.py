"""Imports go one way (README.md, Layout: server -> evaluation/agents -> envs -> core): the toolkit
never imports the server, the baselines' shared code never imports the package that lists the
algorithms built on it, and no module imports itself back, directly or through others. Every import
of every module of the package counts, those inside functions too (they run as soon as the function
does). `importlib.import_module` is a call, not an import statement: the walk does not see league's
lazy names (league/__init__.py), which load once the package has."""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

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
    assert len(graph) > 50 and graph["league.client.parser"]  # the walk found the package
    assert upward(graph) == []


def test_the_walk_sees_what_would_be_an_upward_edge():
    """The rules catch the edges that were removed (the client's check on the server's validation, the
    baselines' export on their registry), written as the old code wrote them, and relative ones."""
    graph = {
        "league.client.check": imports_of(
            "def check():\n    from league.server.sandbox.validation import validate_model\n", "league.client.check"),
        "league.baselines.common.export": imports_of("from league.baselines import load_algorithm\n",
                                                     "league.baselines.common.export"),
        "league.validation.files": imports_of("from ..server import storage\n", "league.validation.files"),
    }
    assert upward(graph) == [("league.baselines.common.export", "league.baselines"),
                             ("league.client.check", "league.server.sandbox.validation"),
                             ("league.validation.files", "league.server"),
                             ("league.validation.files", "league.server.storage")]


# --------------------------------------------------------------------------- the package's entry


def run_python(code: str) -> subprocess.CompletedProcess:
    """`code` in a new interpreter that imports this tree's package."""
    environment = {**os.environ, "PYTHONPATH": str(PACKAGE.parent)}
    return subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True, timeout=120)


# Gymnasium is not among them: the package's import registers the env id with it (about 45 ms).
HEAVY = ("pettingzoo", "tqdm", "scipy", "matplotlib", "league.evaluation", "league.env")


@pytest.mark.parametrize("module", ["league", "league.constants", "league.validation", "league.validation.checks",
                                    "league.validation.limits", "league.exit_codes", "league.client.parser"])
def test_the_package_and_its_light_modules_import_without_the_simulator(module):
    """`import league.constants` runs league/__init__.py first: that must load none of the envs,
    PettingZoo or the evaluation (the sandbox and `league check` import the toolkit this way; every
    `league` command adds the client's commands to its parser)."""
    done = run_python(f"import sys, {module}\nprint([name for name in {HEAVY!r} if name in sys.modules])")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("first, second", [("league", "gymnasium"), ("gymnasium", "league"),
                                           ("league.constants", "gymnasium")])
def test_importing_league_registers_the_gymnasium_id_in_either_order(first, second):
    done = run_python(f"import {first}, {second}\nimport gymnasium\n"
                      "env = gymnasium.make('league/MicroRacer-v0')\n"
                      "print(env.spec.entry_point, env.spec.max_episode_steps, env.reset(seed=0)[0].shape)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["league.env:registered_env", "4000", "(5,)"]


def test_without_league_the_id_is_unknown():
    """The registration above is league's doing, not Gymnasium's."""
    done = run_python("import gymnasium\nprint('league/MicroRacer-v0' in gymnasium.envs.registry)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_the_env_modules_are_not_hidden_by_factories():
    """league.env, league.parallel_env and league.vector_env are the modules, loaded on first use; the
    factories have names of their own."""
    done = run_python("import types, league\n"
                      "print(all(isinstance(m, types.ModuleType) for m in (league.env, league.parallel_env, "
                      "league.vector_env)), league.env.MicroRacerEnv is league.MicroRacerEnv)")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True"]
    import league.parallel_env
    import league.vector_env

    assert league.make_parallel_env is league.parallel_env.parallel_env  # PettingZoo's module convention
    assert league.make_aec_env is league.parallel_env.env
    assert league.make_vector_env is league.vector_env.make_vector_env
    assert set(league.__all__) <= set(dir(league))
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        league.no_such_name  # noqa: B018


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of `graph`: each set of modules that import one another, directly or through
    others (a strongly connected component, sorted; Tarjan's walk), and each module that imports itself."""
    order, lowest, stack, found = {}, {}, [], []

    def visit(module):
        order[module] = lowest[module] = len(order)
        stack.append(module)
        for target in graph[module] & graph.keys():
            if target not in order:
                visit(target)
                lowest[module] = min(lowest[module], lowest[target])
            elif target in stack:
                lowest[module] = min(lowest[module], order[target])
        if lowest[module] == order[module]:  # `module` and those above it on the stack are one component
            component = stack[stack.index(module):]
            del stack[stack.index(module):]
            if len(component) > 1 or module in graph[module]:
                found.append(sorted(component))

    for module in graph:
        if module not in order:
            visit(module)
    return sorted(found)


def test_no_module_imports_itself_back():
    """No circle in the whole package, the server included. A module may import league (for
    __version__): league/__init__.py imports none of the toolkit as it loads, so no circle runs
    through it (compat -> evaluation -> league -> compat was one)."""
    graph = import_graph()
    assert graph["league.evaluation"] >= {"league", "league.parallel_env"}  # the walk sees module-level imports
    assert "league.server.cli" in graph["league.cli"]  # and those in functions (_add_server_commands)
    assert cycles(graph) == []


def test_the_walk_sees_a_circle():
    """Through module-level imports, through imports inside functions only (the circle league.cli
    made with the server's commands, as their code was written), and a package importing itself
    (`from package import submodule` in its own __init__)."""
    assert cycles({"league": {"league.compat"}, "league.compat": {"league.evaluation"},
                   "league.evaluation": {"league"}}) == [["league", "league.compat", "league.evaluation"]]
    in_functions = {
        "league.cli": imports_of("def add_commands(subparsers):\n    from league.server.cli import add_commands\n",
                                 "league.cli"),
        "league.server.cli": imports_of("def main():\n    from league.cli import main\n", "league.server.cli"),
    }
    assert cycles(in_functions) == [["league.cli", "league.server.cli"]]
    itself = imports_of("from league.server.api.routes import health\n", "league.server.api.routes", is_package=True)
    assert cycles({"league.server.api.routes": itself, "league.server.api.routes.health": set()}) == [
        ["league.server.api.routes"]]

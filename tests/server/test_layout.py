"""The server package's layout: the map of league/server/README.md ("Where things are") names every
module and package of league/server and of its packages, and nothing that is not there; core/ is the
bottom of the server (it imports nothing else of it)."""
from __future__ import annotations

import ast
import re
from pathlib import Path

from ..layout import REPO

SERVER = REPO / "league" / "server"
# The map names league/server's modules and packages, and theirs; a deeper package's modules (the
# routers of api/routes/, the revisions of migrations/versions/) are named by their package.
MAP_DEPTH = 2
NAME = re.compile(r"[\w./]+(\.py|/)")  # a module or a package, as the map writes it
DESCRIPTION_INDENT = 8  # a line indented this far continues the description above it


def map_lines(readme: str) -> list[str]:
    """The lines of the code block under "## Where things are"."""
    section = readme.split("\n## Where things are\n", 1)[1].split("\n## ", 1)[0]
    return [line for line in section.split("```", 2)[1].splitlines()[1:] if line.strip()]


def mapped(lines: list[str]) -> set[str]:
    """The paths the map names, relative to league/server: the names that start each line (one or
    several), inside the package named by the nearest line above that is indented less."""
    named, packages = set(), []  # packages: (indent, path) of those the line may be inside
    for line in lines:
        indent = len(line) - len(line.lstrip())
        if indent >= DESCRIPTION_INDENT:
            continue
        names = []
        for word in line.split():
            if not NAME.fullmatch(word):
                break
            names.append(word)
        while packages and packages[-1][0] >= indent:
            packages.pop()
        inside = packages[-1][1] if packages else ""
        named |= {inside + name for name in names}
        if names and names[-1].endswith("/"):
            packages.append((indent, inside + names[-1]))
    return named


def modules_and_packages(package: Path, depth: int) -> set[str]:
    """What the map must name of `package`, relative to league/server: its modules and packages
    (written `name/`), and theirs down to `depth` levels."""
    found = set()
    for path in sorted(package.iterdir()):
        if path.suffix == ".py" and path.name != "__init__.py":
            found.add(path.relative_to(SERVER).as_posix())
        elif (path / "__init__.py").is_file():
            found.add(path.relative_to(SERVER).as_posix() + "/")
            if depth > 1:
                found |= modules_and_packages(path, depth - 1)
    return found


def test_the_map_names_every_module_and_package_of_the_server_and_nothing_else():
    named = mapped(map_lines((SERVER / "README.md").read_text(encoding="utf-8")))
    assert len(named) > 60 and {"app.py", "course/", "course/grading.py", "api/routes/"} <= named
    assert sorted(modules_and_packages(SERVER, MAP_DEPTH) - named) == []  # missing from the map
    assert sorted(path for path in named if not (SERVER / path).exists()) == []  # named, not there


def test_the_map_reader_puts_each_name_in_its_package():
    lines = ["app.py         the app", "               continued: not.py", "api/           the API",
             "  deps.py      shared", "  a.py b.py    two modules, one line", "  routes/      routers",
             "db/", "  models.py    tables", "migrations/    (alembic.ini beside it)"]
    assert mapped(lines) == {"app.py", "api/", "api/deps.py", "api/a.py", "api/b.py", "api/routes/", "db/",
                             "db/models.py", "migrations/"}
    assert sorted(modules_and_packages(SERVER, 1) - mapped(lines))[:2] == ["__main__.py", "backup.py"]


def test_core_imports_nothing_else_of_the_server():
    """The plumbing is what everything else stands on: config, tokens, the clock, the log lines."""
    outside = set()
    for path in sorted((SERVER / "core").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                modules = ["." * node.level + (node.module or "")]
            else:
                continue
            outside |= {f"{path.name}: {module}" for module in modules if module.startswith(".")
                        or module.startswith("league.server") and not module.startswith("league.server.core")}
    assert sorted(outside) == []

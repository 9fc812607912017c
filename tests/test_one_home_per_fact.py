"""One home per fact: the status words (league.statuses), the default points table
(league.championship.DEFAULT_POINTS) and the model suffixes (league.constants.MODEL_SUFFIXES) are
written once; the rest of the package imports them and the pages read them from the server
(league.server.pages). Each detector here looks for a fact's values written out again in the
package's Python (parsed with ast), HTML (its attributes, with html.parser) or JavaScript, and is shown
to catch a copy."""
from __future__ import annotations

import ast
import json
import re
from functools import cache
from html.parser import HTMLParser
from pathlib import Path

from league import statuses
from league.championship import DEFAULT_POINTS
from league.constants import MODEL_SUFFIXES

PACKAGE = Path(__file__).resolve().parents[1] / "league"
WORDS = set(statuses.SUBMISSION_STATUSES + statuses.JOB_STATUSES + statuses.RACE_STATUSES)
SUFFIX = re.compile(r"(?<![\w.])(" + "|".join(re.escape(s) for s in MODEL_SUFFIXES) + r")(?![\w.])")

def package_files(suffix: str) -> list[Path]:
    return sorted(PACKAGE.rglob(f"*{suffix}"))


@cache  # each file is parsed once for the three detectors
def literals(source: str) -> list[ast.AST]:
    """The collections written out in Python source (tuples, lists, sets, dict keys) and its strings."""
    return [node for node in ast.walk(ast.parse(source))
            if isinstance(node, (ast.Tuple, ast.List, ast.Set, ast.Dict)) or isinstance(node, ast.Constant)]


def values(node: ast.AST) -> list:
    items = node.keys if isinstance(node, ast.Dict) else node.elts
    return [item.value if isinstance(item, ast.Constant) else None for item in items]


def python_status_copies(source: str) -> list:
    """Collections of two or more status words (a group of statuses written again)."""
    found = []
    for node in literals(source):
        if not isinstance(node, ast.Constant):
            words = values(node)
            if len(words) >= 2 and all(isinstance(w, str) and w in WORDS for w in words):
                found.append(words)
    return found


def python_points_copies(source: str) -> list:
    """The points table as a collection of numbers, or spelled in a string (help texts)."""
    table, spelled = list(DEFAULT_POINTS), re.compile(r"\D+".join(map(str, DEFAULT_POINTS)))
    found = []
    for node in literals(source):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, str) and spelled.search(node.value):
                found.append(node.value)
        elif values(node) == table:
            found.append(table)
    return found


def suffix_copies(text: str) -> set[str]:
    """Three or more model suffixes together: the list written out (one or two are an example)."""
    found = set(SUFFIX.findall(text))
    return found if len(found) >= 3 else set()


def python_suffix_copies(source: str) -> list:
    found = []
    for node in literals(source):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, str) and suffix_copies(node.value):
                found.append(node.value)
        elif suffix_copies(" ".join(v for v in values(node) if isinstance(v, str))):
            found.append(values(node))
    return found


class Attributes(HTMLParser):
    def __init__(self, text: str):
        super().__init__()
        self.values: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.values += [value for _, value in attrs if value]


def html_copies(text: str) -> list[str]:
    """Attribute values that spell the points table or the suffix list (an input's value, an accept=)."""
    numbers = ", ".join(map(str, DEFAULT_POINTS))
    return [value for value in Attributes(text).values
            if re.sub(r"[,\s]+", ", ", value.strip()) == numbers or suffix_copies(value.replace(",", " "))]


JS_STATUS = "|".join(sorted(WORDS))
JS_COPIES = (re.compile(rf'[!=]==\s*"({JS_STATUS})"'),  # status === "ready"
             re.compile(rf'\[\s*"({JS_STATUS})"(\s*,\s*"({JS_STATUS})")+\s*\]'),  # ["done", "failed"]
             re.compile(r"\D+".join(map(str, DEFAULT_POINTS))))


def js_copies(text: str) -> list[str]:
    return [match.group(0) for pattern in JS_COPIES for match in pattern.finditer(text)] + \
        sorted(suffix_copies(text))


def copies(suffix: str, *detectors) -> dict[str, list]:
    found = {}
    for path in package_files(suffix):
        hits = [hit for detect in detectors for hit in detect(path.read_text())]
        if hits:
            found[str(path.relative_to(PACKAGE.parent))] = hits
    return found


def test_python_imports_the_facts_from_their_homes():
    """Only the homes write the facts out (and the detectors see them there)."""
    found = copies(".py", python_status_copies, python_points_copies, python_suffix_copies)
    assert found == {"league/statuses.py": [list(statuses.SUBMISSION_STATUSES), ["queued", "running", "done"]],
                     "league/championship.py": [list(DEFAULT_POINTS)], "league/constants.py": [list(MODEL_SUFFIXES)]}


def test_the_pages_read_the_facts_from_the_server():
    assert copies(".html", html_copies) == {}
    assert copies(".js", js_copies) == {}


def test_the_detectors_catch_a_copy():
    assert python_status_copies('TERMINAL = {"ready", "rejected", "failed"}') == [["ready", "rejected", "failed"]]
    assert python_status_copies('kinds = ("ready", "onnx")') == []
    assert python_points_copies("points = [25, 18, 15, 12, 10, 8, 6, 4, 2, 1]") == [list(DEFAULT_POINTS)]
    assert python_points_copies('help = "default 25,18,15,12,10,8,6,4,2,1"') == ["default 25,18,15,12,10,8,6,4,2,1"]
    assert python_suffix_copies('ACCEPT = (".onnx", ".pt", ".pth")') == [[".onnx", ".pt", ".pth"]]
    assert python_suffix_copies('name = "model.onnx" if onnx else "model.pt"') == []
    assert html_copies('<input id="champ-points" value="25, 18, 15, 12, 10, 8, 6, 4, 2, 1">') != []
    assert html_copies('<input type="file" accept=".onnx,.pt,.pth,.ts">') != []
    assert html_copies('<input type="file" accept="{{ model_suffixes }}">') == []
    assert js_copies('if (s.status === "ready" && !["done", "failed"].includes(e.status))') == \
        ['=== "ready"', '["done", "failed"]']
    assert js_copies("if (s.status === READY && !ENDED.includes(e.status))") == []


def test_the_pages_get_the_facts(tmp_path):
    """What the pages read instead: the layout's data-statuses and the templates' values."""
    from league.server.core.config import Settings
    from league.server.pages import page_facts

    facts = page_facts(Settings(data_dir=tmp_path))
    assert json.loads(facts["statuses"])["READY"] == statuses.READY
    assert json.loads(facts["statuses"])["ENDED"] == list(statuses.ENDED)
    assert facts["default_points"] == "25, 18, 15, 12, 10, 8, 6, 4, 2, 1"
    assert facts["model_suffixes"] == ".onnx,.pt,.pth,.ts,.jit,.torchscript"

"""league.spreadsheet: CSV whose cells no spreadsheet runs as formulas, whatever it splits lines on."""
from __future__ import annotations

import csv

import pytest

from league.spreadsheet import csv_text, safe_text

from .formulas import formula_cells

HOSTILE = [
    "fast;=2+5;=cmd|' /C calc'!A0",  # issue 22: Excel splitting on ';' made cells starting with '='
    "=1+1", "+1", "-1+1", "@SUM(A1)", "\t=1", "\r=1", "a\n=1", "a\r\n@1", 'x;"=1"', "x, =1", "x|=1", "x; '=1",
    "x;\t=1", "x\u2028=1", "x;;=1", '=HYPERLINK("http://evil.example")', "-5",
]


def test_no_cell_starts_a_formula_whatever_the_separator_and_numbers_stay_numbers():
    rows = [[rank, name, -1.5, 3] for rank, name in enumerate(HOSTILE, 1)] + [[None, "no agent", None, None]]
    text = csv_text(["rank", "agent", "mean_return", "completed"], rows)
    assert formula_cells(text) == set()
    header, *lines = text.splitlines(keepends=True)
    assert header == "rank,agent,mean_return,completed\n"
    parsed = list(csv.reader(lines, quoting=csv.QUOTE_NONNUMERIC))  # the unquoted cells are read as numbers
    assert [row[0] for row in parsed[:-1]] == list(range(1, len(HOSTILE) + 1))
    assert all(row[2:] == [-1.5, 3] for row in parsed[:-1]) and parsed[-1] == ["", "no agent", "", ""]


def test_the_old_grade_sheet_made_formulas_when_split_on_semicolons():
    """What issue 22 found, kept as the check's own check: a cell that starts plain is not enough."""
    old = f"rank,agent\n1,{HOSTILE[0]}\n"
    assert formula_cells(old) == {"=2+5", "=cmd|' /C calc'!A0"}


@pytest.mark.parametrize("text, safe", [
    ("fast;=2+5;=cmd|' /C calc'!A0", "fast;'=2+5;'=cmd|' /C calc'!A0"),
    ("=1", "'=1"), ("a\t=b", "a =b"), ("x; \"=1", "x; \"'=1"), ("plain name", "plain name"), ("a-b+c@d", "a-b+c@d"),
])
def test_an_apostrophe_goes_before_each_trigger_where_a_cell_may_begin(text, safe):
    assert safe_text(text) == safe

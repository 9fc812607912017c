"""CSV that spreadsheets open as data, never as formulas (`csv_text`): every CSV the league writes
(the server's grade sheets, `league submissions --csv`, the tokens of `league users import`) goes
through it.

A spreadsheet runs a cell that starts with = + - or @ as a formula, and where cells begin depends
on how it splits lines: on commas, but Excel in much of Europe splits on semicolons, and import
dialogs offer tabs and '|'; quotes protect a cell only from a parser that splits on the same
character. So a text cell is neutralised wherever a cell could begin, whatever the separator:
control characters (tab, CR, LF, ...) become spaces, and an apostrophe goes before a trigger at
the start and after any of , ; |  (past spaces and quotes, which a parser may strip). Text cells
are quoted, numbers written as numbers.
"""
from __future__ import annotations

import csv
import io
import unicodedata
from collections.abc import Iterable

FORMULA_TRIGGERS = frozenset("=+-@")  # tab and CR too, but those become spaces first
SEPARATORS = frozenset(",;|")  # tab too, likewise
SKIPPED = frozenset(" \"'")  # between a separator and a trigger: what a parser may trim or unquote
CONTROL = ("Cc", "Zl", "Zp")  # Unicode categories of control characters and line/paragraph separators


def safe_text(text: str) -> str:
    """`text` with no control characters and an apostrophe before every formula trigger that
    starts it or follows a separator."""
    out, cell_may_begin = [], True
    for char in text:
        if unicodedata.category(char) in CONTROL:
            char = " "
        if cell_may_begin and char in FORMULA_TRIGGERS:
            out.append("'")
        out.append(char)
        cell_may_begin = char in SEPARATORS or (cell_may_begin and char in SKIPPED)
    return "".join(out)


def csv_text(header: list[str], rows: Iterable[Iterable]) -> str:
    """A CSV file: the header (column names, quoted only where CSV needs it), then the rows: numbers
    as they are, None as an empty cell, anything else as quoted, safe text."""
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerow([safe_text(name) for name in header])
    writer = csv.writer(out, quoting=csv.QUOTE_NONNUMERIC, lineterminator="\n")
    writer.writerows([_cell(value) for value in row] for row in rows)
    return out.getvalue()


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return value
    return safe_text(str(value))

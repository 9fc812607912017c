"""What a spreadsheet would run as a formula in a CSV text, whatever it splits lines on: the check
of the grade sheets (tests/test_spreadsheet.py, tests/server/api/routes/test_leaderboard.py)."""
from __future__ import annotations

import csv
import io

TRIGGERS = ("=", "+", "-", "@", "\t", "\r")
SEPARATORS = (",", ";", "\t")


def is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def formula_cells(text: str) -> set[str]:
    """The cells of `text` a spreadsheet would run, splitting on commas, semicolons or tabs: with the
    csv module (quotes honoured) and by plain splitting (quotes taken as text), each also with its
    spaces trimmed. Numbers (-1.5) are not formulas."""
    cells = []
    for separator in SEPARATORS:
        cells += [cell for row in csv.reader(io.StringIO(text), delimiter=separator) for cell in row]
        cells += [cell for line in text.splitlines() for cell in line.split(separator)]
    return {cell for cell in cells for candidate in (cell, cell.strip())
            if candidate.startswith(TRIGGERS) and not is_number(candidate)}

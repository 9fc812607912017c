"""What the client prints: tables (aligned columns, or CSV) and the API's times in this machine's zone."""
from __future__ import annotations

import sys

from league.spreadsheet import csv_text


def print_table(header: list[str], rows: list[list], as_csv: bool) -> None:
    """The rows under the header, in columns aligned with spaces, or as CSV."""
    if as_csv:
        sys.stdout.write(csv_text(header, rows))
        return
    cells = [[str(c) for c in row] for row in [header, *rows]]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]
    for row in cells:
        print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())


def local_time(text: str | None) -> str:
    """A UTC time of the API in this machine's time zone, with the zone: 2026-12-02 00:59 CET."""
    if not text:
        return ""
    from datetime import datetime

    return datetime.fromisoformat(text).astimezone().strftime("%Y-%m-%d %H:%M %Z")

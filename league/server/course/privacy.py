"""Who sees a course's boards, and under which names.

A course's `board_visibility` says who sees its boards (the leaderboard, its races and replays,
its championships and standings): `public` (anyone), `members` (its logged-in students and
instructors) or `instructors`. Members who may see a board see real names; anyone else who may
(a visitor of a public board, or a student looking at a race of their own car on a board closed to
them) sees each student as their display name, else as a "Student N" pseudonym; baselines keep
their names. The check itself is `league.server.api.deps.board_names`, the one every board route calls.

Pseudonyms are numbers drawn at random (`secrets`) for each account of a course when it is made
(users.pseudonym, unique in the course): stable for the course's life and no function of the id, so
that one board, or several, tells nothing of the others' ids nor of the roster's order, which is
often alphabetical.
"""
from __future__ import annotations

import gzip
import json
import re
import secrets
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from league.server.course.accounts import clean_name
from league.server.db.models import BASELINE, VISIBILITY_INSTRUCTORS, VISIBILITY_MEMBERS, VISIBILITY_PUBLIC

AUDIENCE = {VISIBILITY_PUBLIC: "anyone", VISIBILITY_MEMBERS: "the course's students and instructors, logged in",
            VISIBILITY_INSTRUCTORS: "the course's instructors only"}
PSEUDONYMS = 999_999  # "Student 1" to "Student 999999": a course of 1,000 leaves 99.9 % of them free
PSEUDONYM = re.compile(r"student\s*\d+", re.IGNORECASE)
UNKNOWN = "(unknown)"  # an owner whose account is gone, or has no pseudonym in the course


def draw_pseudonym(taken: Callable[[int], bool]) -> int:
    """A random pseudonym number that `taken` says is free in the course."""
    while True:
        number = 1 + secrets.randbelow(PSEUDONYMS)
        if not taken(number):
            return number


def pseudonym(number: int) -> str:
    return f"Student {number}"


def clean_display_name(text: str | None) -> str | None:
    """A display name cleaned as names are (accounts.clean_name); None for an empty one (unset)."""
    if text is None or not text.strip():
        return None
    name = clean_name(text)
    if PSEUDONYM.fullmatch(name):
        raise ValueError(f"the display name {name!r} looks like the pseudonym of a student who has none: "
                         "choose another")
    return name


@dataclass(frozen=True)
class Names:
    """How one viewer sees the owners on a course's boards: `real` names, or public ones (display
    names, else pseudonyms) for everyone but the baselines and the viewer."""

    real: bool
    viewer_id: int | None = None
    display_names: dict[int, str] = field(default_factory=dict)  # user id -> display name (public view)
    pseudonyms: dict[int, int] = field(default_factory=dict)  # user id -> their number in the course

    def owner(self, owner_id: int | None, name: str, role: str | None) -> str:
        if self.real or role == BASELINE or owner_id is None or owner_id == self.viewer_id:
            return name
        if owner_id in self.display_names:
            return self.display_names[owner_id]
        return pseudonym(self.pseudonyms[owner_id]) if owner_id in self.pseudonyms else UNKNOWN

    def rows(self, rows: list[dict]) -> list[dict]:
        """Board rows (with "owner", "owner_id", "owner_role") with their owners renamed."""
        if self.real:
            return rows
        return [{**row, "owner": self.owner(row["owner_id"], row["owner"], row["owner_role"])} for row in rows]

    def people(self, people: list[dict] | None, owners: dict[int, Any]) -> list[dict] | None:
        """A race's entrants or classification (rows with "submission_id" and "owner"), renamed;
        `owners`: submission id -> its owner (a User)."""
        if self.real or people is None:
            return people
        return [{**row, "owner": self._entrant_owner(row, owners)} for row in people]

    def replay(self, data: bytes, entrants: list[dict], owners: dict[int, Any]) -> bytes | None:
        """A stored replay (gzip JSON) with its car names ("agent (owner)") renamed; None: as stored."""
        if self.real:
            return None
        replay = json.loads(gzip.decompress(data))
        shown = [self._entrant_owner(entrant, owners) for entrant in entrants]
        replay["names"] = [f"{entrant['name']} ({owner})" for entrant, owner in zip(entrants, shown)]
        for row in replay.get("classification", []):
            car = int(row["car"].removeprefix("car_"))
            row.update({"name": replay["names"][car]}, **({"owner": shown[car]} if "owner" in row else {}))
        return json.dumps(replay, separators=(",", ":")).encode()

    def _entrant_owner(self, row: dict, owners: dict[int, Any]) -> str:
        owner = owners.get(row["submission_id"])
        if owner is None:  # the submission is gone: its owner is not named
            return UNKNOWN
        return self.owner(owner.id, owner.name, owner.role)

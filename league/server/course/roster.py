"""Rosters as spreadsheets export them: a file in, students out.

`read_roster(data)` decodes the file (UTF-8 with or without Excel's BOM, or UTF-16 with its BOM as
Excel's "Unicode Text" writes it), finds the delimiter (comma, semicolon or tab) from the header
line, recognises the header's columns in common spellings (name, or first and last name; email;
student id) whatever their case and accents, or reads one name a line when there is no header.
Every line becomes a `RosterRow` or a `RosterProblem` with its line number: one bad line never
hides the others.

Canvas's gradebook export (Grades > Export: `Student, ID, SIS User ID, SIS Login ID, Section, <one
column an assignment>`, then a "Points Possible" line; the names written "Last, First") is read as
Canvas writes it: its ID (the Canvas user ID), SIS User ID (our student id) and SIS Login ID are
kept, which the Canvas grade file echoes (league.server.course.grading), and its lines that are not
students (Points Possible, the posting-policy line, the course's Test Student) are set aside.
Moodle's exports (the participants page's download: `First name, Last name, Email address, ID
number`; the gradebook's: `First name, Last name, ID number, Institution, Department, Email
address, ...`) need nothing of their own: ID number is the student id.

`import_roster(session, ...)` then creates the rows' students, skips those already enrolled
(matched by their ids when the line gives them: Canvas ID, student id, SIS Login ID, email; else
by name) and reports each line it did not create. The API (`POST /api/users/roster`) and `league
users import` both call these two.
"""
from __future__ import annotations

import codecs
import csv
import io
import itertools
import unicodedata
from collections.abc import Iterator
from dataclasses import dataclass, field

from sqlalchemy import select
from sqlalchemy.orm import Session

from league.server.course.accounts import (
    clean_canvas_id, clean_email, clean_login, clean_name, clean_student_id, identity_key,
)
from league.server.db import crud
from league.server.db.models import STUDENT, Course, User

MAX_ROSTER_BYTES = 1024 * 1024
MAX_ROSTER_LINES = 10_000
DELIMITERS = {",": "comma", ";": "semicolon", "\t": "tab"}
# Header labels as `label_key` spells them (accents, case, spaces and punctuation dropped), by field;
# within a field the first label present wins (Canvas exports both "ID" and "SIS User ID").
FULL_NAME = ("fullname", "studentname", "displayname", "student", "participant", "nomcomplet", "nombrecompleto",
             "nomecompleto", "vollstandigername", "volledigenaam", "imieinazwisko")
# "Name" alone: the full name, but the surname beside a first-name column (German "Name, Vorname",
# French "Nom, Prénom") and the given name beside a surname column (Spanish "Nombre, Apellidos").
AMBIGUOUS_NAME = ("name", "nom", "nombre", "nome", "naam")
FIRST_NAME = ("firstname", "givenname", "givennames", "forename", "forenames", "first", "prenom", "prenoms",
              "vorname", "voornaam", "imie")
LAST_NAME = ("lastname", "surname", "surnames", "familyname", "familynames", "last", "nachname", "familienname",
             "achternaam", "cognome", "apellidos", "apellido", "sobrenome", "nomdefamille", "nazwisko")
EMAIL = ("email", "emailaddress", "emailadresse", "mail", "mailaddress", "courriel", "correoelectronico", "correo")
STUDENT_ID = ("studentid", "studentnumber", "studentno", "idnumber", "sisuserid", "sisid", "matriculationnumber",
              "matriculation", "matricnumber", "matricno", "matrikelnummer", "matrikelnr", "registrationnumber",
              "numeroetudiant", "numerodetudiant", "matricola", "studentnummer", "id")
SIS_LOGIN_ID = ("sisloginid",)
FIELDS = {"full": FULL_NAME, "name": AMBIGUOUS_NAME, "first": FIRST_NAME, "last": LAST_NAME, "email": EMAIL,
          "student_id": STUDENT_ID, "sis_login_id": SIS_LOGIN_ID}
# Canvas's gradebook export, as its importer recognises it (canvas-lms GradebookImporter): "Student",
# then "ID", and "Section" within the next five columns (after SIS User ID, SIS Login ID, Integration
# ID, Root Account, as present); its "ID" is the Canvas user ID, not the school's
CANVAS_FIRST = ("student", "id")
CANVAS_SECTION = "section"
CANVAS_POINTS_POSSIBLE = "Points Possible"
CANVAS_TEST_STUDENT = "Student, Test"  # the account of Canvas's Student View, in every export
CANVAS_POSTING = ("muted", "manual posting")  # how the cells of its posting-policy line start (any case)
HEADER_HELP = ("name the columns in the first line, e.g. name,email,student id (or first name,last name,...), "
               "or give one name a line without a header")


class RosterError(ValueError):
    """The file as a whole cannot be read (message shown to the instructor)."""


@dataclass(frozen=True)
class RosterRow:
    line: int
    name: str
    email: str | None = None
    student_id: str | None = None
    canvas_id: str | None = None
    sis_login_id: str | None = None


@dataclass(frozen=True)
class RosterProblem:
    """A line not created: skipped (the student is enrolled already) or an error."""

    line: int
    name: str | None
    reason: str


@dataclass
class Roster:
    delimiter: str
    columns: dict[str, str]  # field -> the header's own spelling; empty without a header
    rows: list[RosterRow] = field(default_factory=list)
    errors: list[RosterProblem] = field(default_factory=list)
    layout: str = "plain"  # or "canvas": Canvas's gradebook export
    ignored: list[RosterProblem] = field(default_factory=list)  # lines that are not students (Canvas's)


def read_roster(data: bytes) -> Roster:
    """The file's rows and bad lines (RosterError if it cannot be read at all)."""
    if len(data) > MAX_ROSTER_BYTES:
        raise RosterError(f"roster too large ({MAX_ROSTER_BYTES // 1024 // 1024} MB at most)")
    text = decode(data)
    if len(text.splitlines()) > MAX_ROSTER_LINES:
        raise RosterError(f"the roster has more than {MAX_ROSTER_LINES} lines: split it into several files")
    hint = _separator_hint(text)
    skip = 1 if hint else 0  # the hint's own line
    delimiter, columns = _sniff_header(text, [hint] if hint else list(DELIMITERS), skip)
    if columns:
        return _read_with_header(text, delimiter, skip)
    return _read_names(text, skip)


def _separator_hint(text: str) -> str | None:
    """The delimiter of a first line such as "sep=;", which Excel reads and some exports write."""
    first = next((line.strip() for line in text.splitlines() if line.strip()), "")
    if len(first) == 5 and first.lower().startswith("sep=") and first[4] in DELIMITERS:
        return first[4]
    return None


def decode(data: bytes) -> str:
    if data.startswith(b"PK\x03\x04"):
        raise RosterError("this is a spreadsheet workbook (.xlsx or .ods), not a CSV file: save it as CSV UTF-8 "
                          "(Excel: File > Save As > CSV UTF-8) and upload that")
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding = "utf-16"  # Excel's "Unicode Text": UTF-16 with a BOM, tab-separated
    else:
        encoding = "utf-8-sig"  # Excel's "CSV UTF-8" starts with a BOM
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as error:
        line = data[:error.start].count(b"\n") + 1
        raise RosterError(f"the roster is not {encoding.removesuffix('-sig').upper()} text (line {line}): save it "
                          "as CSV UTF-8 (Excel: File > Save As > CSV UTF-8)") from None


def label_key(label: str) -> str:
    """A header label as FIELDS spell it: 'E-Mail', 'e_mail' and 'EMAIL ' -> 'email'; 'Prénom' -> 'prenom'."""
    decomposed = unicodedata.normalize("NFKD", label.casefold())
    return "".join(char for char in decomposed if char.isalnum() and not unicodedata.combining(char))


def header_columns(cells: list[str]) -> dict[str, int]:
    """The field -> column index of a header line; {} when it names no field."""
    keys = [label_key(cell) for cell in cells]
    columns = {}
    for field_name, labels in FIELDS.items():
        found = [(labels.index(key), index) for index, key in enumerate(keys) if key in labels]
        if found:
            columns[field_name] = min(found)[1]
    if is_canvas(keys):  # its ID is Canvas's own: the student id is the SIS User ID, or none
        columns["canvas_id"] = 1
        if "sisuserid" in keys:
            columns["student_id"] = keys.index("sisuserid")
        else:
            columns.pop("student_id", None)
    return columns


def is_canvas(keys: list[str]) -> bool:
    """Whether a header (as `label_key` spells it) is that of Canvas's gradebook export."""
    return tuple(keys[:2]) == CANVAS_FIRST and CANVAS_SECTION in keys[2:7]


def _sniff_header(text: str, delimiters: list[str], skip: int) -> tuple[str, dict[str, int]]:
    """The delimiter under which the first line names most fields, and those fields' columns."""
    best = (delimiters[0], {})
    for delimiter in delimiters:
        first = _record(text, delimiter, skip)
        columns = header_columns(first[1]) if first else {}
        if len(columns) > len(best[1]):
            best = (delimiter, columns)
    return best


def _records(text: str, delimiter: str) -> Iterator[tuple[int, list[str]]]:
    """(first line number, cells) of each non-blank record; a quoted cell may span lines."""
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter, skipinitialspace=True)
    line = 1
    try:
        for cells in reader:
            if any(cell.strip() for cell in cells):
                yield line, cells
            line = reader.line_num + 1
    except csv.Error as error:
        raise RosterError(f"line {reader.line_num}: {error}") from None


def _record(text: str, delimiter: str, index: int) -> tuple[int, list[str]] | None:
    """The index-th non-blank record, read no further."""
    return next(itertools.islice(_records(text, delimiter), index, None), None)


def _read_with_header(text: str, delimiter: str, skip: int) -> Roster:
    records = list(_records(text, delimiter))[skip:]
    line, cells = records[0]
    columns = header_columns(cells)
    name_columns = _name_columns(columns)
    if not name_columns:
        raise RosterError(f"line {line}: no name column in {_shown(cells)}: {HEADER_HELP}")
    canvas = "canvas_id" in columns
    roster = Roster(delimiter, {f: cells[i].strip() for f, i in columns.items()},
                    layout="canvas" if canvas else "plain")
    width = len(cells)
    for line, cells in records[1:]:
        not_student = canvas and canvas_not_student(cells)
        if not_student:
            roster.ignored.append(RosterProblem(line, None, not_student))
        else:
            _add_row(roster, line, cells, columns, name_columns, width)
    return roster


def canvas_not_student(cells: list[str]) -> str | None:
    """Why a line of Canvas's export is not a student's (as Canvas's own importer skips them), else None."""
    student = cells[0].strip()
    if CANVAS_POINTS_POSSIBLE in student:
        return "Canvas's Points Possible line (each assignment's maximum), not a student"
    if student == CANVAS_TEST_STUDENT:
        return "Canvas's Test Student (the account of its Student View), not a person"
    if all(not cell.strip() or cell.strip().casefold().startswith(CANVAS_POSTING) for cell in cells):
        return "Canvas's line of grade posting policies, not a student"
    return None


def canvas_name(sortable: str) -> str:
    """A name as Canvas exports it, "Lovelace, Ada", as the league writes it: "Ada Lovelace"."""
    last, comma, first = sortable.partition(",")
    return f"{first.strip()} {last.strip()}" if comma and first.strip() and last.strip() else sortable


def _name_columns(columns: dict[str, int]) -> list[int]:
    """The columns whose cells, joined by a space, make the name (given name first)."""
    if "full" in columns:
        return [columns["full"]]
    first, last, name = columns.get("first"), columns.get("last"), columns.get("name")
    if first is not None and last is not None:
        return [first, last]
    if name is not None and (first is not None or last is not None):
        return [first, name] if first is not None else [name, last]
    return [column for column in (name, first, last) if column is not None][:1]


def _add_row(roster: Roster, line: int, cells: list[str], columns: dict[str, int], name_columns: list[int],
             width: int) -> None:
    def cell(index: int | None) -> str:
        return cells[index] if index is not None and index < len(cells) else ""

    raw_name = " ".join(cell(index) for index in name_columns)
    if roster.layout == "canvas":
        raw_name = canvas_name(raw_name)
    problems, values = [], {}
    if sum(1 for value in cells[width:] if value.strip()):
        problems.append(f"{len(cells)} cells where the header has {width}: put cells that hold a "
                        f"{DELIMITERS[roster.delimiter]} in double quotes")
    for key, clean, raw in (("name", clean_name, raw_name), ("email", clean_email, cell(columns.get("email"))),
                            ("student_id", clean_student_id, cell(columns.get("student_id"))),
                            ("canvas_id", clean_canvas_id, cell(columns.get("canvas_id"))),
                            ("sis_login_id", clean_login, cell(columns.get("sis_login_id")))):
        try:
            values[key] = clean(raw)
        except ValueError as error:
            problems.append(str(error))
    if problems:
        roster.errors.append(RosterProblem(line, values.get("name") or " ".join(raw_name.split())[:100] or None,
                                           "; ".join(problems)))
    else:
        roster.rows.append(RosterRow(line, **values))


def _read_names(text: str, skip: int) -> Roster:
    """A file without a header: one name a line (several cells in its first line: an unknown header)."""
    records = list(_records(text, ","))[skip:]
    if not records:
        raise RosterError("the roster holds no names")
    line = records[0][0]
    for delimiter in DELIMITERS:
        first = _record(text, delimiter, skip)[1]
        if sum(1 for value in first if value.strip()) > 1:
            raise RosterError(f"line {line}: no column name recognised in {_shown(first)}: {HEADER_HELP}")
    roster = Roster(",", {})
    for line, cells in records:
        values = [value for value in cells if value.strip()]
        try:
            if len(values) > 1 or any(sign in values[0] for sign in ";\t"):
                raise ValueError("several cells in a roster without a header: put a name that holds a comma "
                                 "in double quotes, or " + HEADER_HELP)
            roster.rows.append(RosterRow(line, clean_name(values[0])))
        except ValueError as error:
            roster.errors.append(RosterProblem(line, " ".join(" ".join(values).split())[:100] or None, str(error)))
    return roster


def _shown(cells: list[str]) -> str:
    return ", ".join(repr(cell.strip()[:40]) for cell in cells[:8]) + (", ..." if len(cells) > 8 else "")


# --------------------------------------------------------------------------- import


@dataclass
class RosterReport:
    created: list[tuple[User, str]] = field(default_factory=list)  # with their tokens (shown once)
    skipped: list[RosterProblem] = field(default_factory=list)  # enrolled already, or named twice in the file
    errors: list[RosterProblem] = field(default_factory=list)


@dataclass(frozen=True)
class Known:
    """A student the roster may name again: enrolled before (line None) or created from a line."""

    user: User
    line: int | None


class Enrolment:
    """Who the roster can match: by their ids (IDENTIFIERS) the course's students, by name every account
    (names are unique in the league), and the students created from earlier lines."""

    def __init__(self, session: Session, course: Course) -> None:
        self.course = course
        self.by_key: dict[tuple[str, str], Known] = {}
        for user in session.scalars(select(User)):
            self.add(Known(user, None))

    def add(self, known: Known) -> None:
        self.by_key[("name", identity_key(known.user.name))] = known
        if known.user.course_id == self.course.id and known.user.role == STUDENT:
            for key in identifier_keys(known.user):
                self.by_key[key] = known

    def match(self, row: RosterRow) -> tuple[Known | None, str]:
        """The student the row names, and how it was found (an IDENTIFIERS label, or "name")."""
        found = {how: self.by_key[(how, value)] for how, value in identifier_keys(row) if (how, value) in self.by_key}
        if len({id(known.user) for known in found.values()}) > 1:
            raise ValueError(" but ".join(f"its {how} is that of {who(known)}" for how, known in found.items()))
        if found:
            return next(iter(found.values())), next(iter(found))
        named = self.by_key.get(("name", identity_key(row.name)))
        return named, "name"


# how a roster line and a student are matched (before their names), by their identifiers: label, attribute
IDENTIFIERS = (("Canvas ID", "canvas_id"), ("student id", "student_id"), ("SIS Login ID", "sis_login_id"),
               ("email", "email"))
# the order messages name them in: the school's ids first, as before Canvas's were kept
SAID = tuple(pair for label in ("email", "student id", "Canvas ID", "SIS Login ID") for pair in IDENTIFIERS
             if pair[0] == label)
ANY_CASE = ("sis_login_id", "email")  # Canvas's logins and addresses are one whatever their case; ids are not


def identifier_keys(person: RosterRow | User) -> list[tuple[str, str]]:
    return [(label, identity_key(value) if attribute in ANY_CASE else value) for label, attribute in IDENTIFIERS
            if (value := getattr(person, attribute))]


def who(known: Known) -> str:
    return f"line {known.line} ({known.user.name})" if known.line else f"{known.user.name!r}"


def import_roster(session: Session, *, course: Course, created_by: User | None, roster: Roster) -> RosterReport:
    """Create the students the roster names that are not enrolled yet; fill in the email and student
    id of enrolled students who had none. Adds and flushes; the caller commits. The checks are those
    of crud.create_user, made against every account at once: run it under crud.lock_user (two
    rosters at once may still collide on a name: the database's unique indexes refuse the second)."""
    enrolment = Enrolment(session, course)
    report = RosterReport(skipped=list(roster.ignored), errors=list(roster.errors))
    for row in roster.rows:
        try:
            known, how = enrolment.match(row)
            if known is None:
                user, token = crud.add_user(session, name=row.name, role=STUDENT, course=course, created_by=created_by,
                                            with_token=True, email=row.email, student_id=row.student_id,
                                            canvas_id=row.canvas_id, sis_login_id=row.sis_login_id)
                enrolment.add(Known(user, row.line))
                report.created.append((user, token))
            else:
                report.skipped.append(RosterProblem(row.line, row.name, same_student(enrolment, known, how, row)))
        except ValueError as error:
            report.errors.append(RosterProblem(row.line, row.name, str(error)))
    report.errors.sort(key=lambda problem: problem.line)
    report.skipped.sort(key=lambda problem: problem.line)
    session.flush()
    return report


def same_student(enrolment: Enrolment, known: Known, how: str, row: RosterRow) -> str:
    """Why the row is skipped (after recording the identifiers the student lacked), or ValueError if
    the row names someone else."""
    user = known.user
    if user.course_id != enrolment.course.id or user.role != STUDENT:
        raise ValueError(f"the name {row.name!r} is another account's: give this student a name of their own "
                         "(e.g. with a middle initial)")
    for label, attribute in SAID:
        theirs, given = getattr(user, attribute), getattr(row, attribute)
        if theirs and given and identity_key(theirs) != identity_key(given):
            twins = "; if they are two people, give them distinct names (e.g. with a middle initial)"
            raise ValueError(f"{who(known)} has the same {how} but the {label} {theirs!r}, not {given!r}"
                             + (twins if how == "name" else ""))
    filled = [label for label, attribute in SAID if getattr(row, attribute) and not getattr(user, attribute)]
    for _, attribute in IDENTIFIERS:
        setattr(user, attribute, getattr(user, attribute) or getattr(row, attribute))
    enrolment.add(known)
    alias = f" as {user.name!r}" if identity_key(user.name) != identity_key(row.name) else ""
    where = f"the same student as line {known.line}" if known.line else f"already a student{alias}"
    recorded = f"; their {' and '.join(filled)} recorded" if filled else ""
    revoked = "; their account is revoked (a new token restores it)" if not user.active else ""
    return f"{where} (same {how}){recorded}{revoked}"

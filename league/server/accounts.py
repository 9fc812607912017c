"""What a person's fields may hold: a name, an email address, a student id.

Every way in (the API, a roster, `league users add`) cleans its values here. Names are decided by
Unicode category, not by a list of characters that happen to be bad: letters of any script and
their marks, digits, spaces, apostrophes and hyphens, and the few signs names or old accounts use.
A name must start with a letter, a digit or an apostrophe ('t Hooft) and hold a letter, so that
spreadsheet formulas (=SUM(A1), +1, @cmd, -) and junk cells (#N/A, 42) are refused, not stored.
Each function returns the cleaned value or raises ValueError with a message for the instructor.
"""
from __future__ import annotations

import unicodedata

from email_validator import EmailNotValidError, validate_email

NAME_MAX = 100  # characters (the users.name column)
EMAIL_MAX = 254  # characters, RFC 5321's limit (the users.email column)
STUDENT_ID_MAX = 64  # characters (the users.student_id column)
APOSTROPHES = frozenset("'\u2019\u02bc")  # O'Brien as typed, as word processors curl it, the letter apostrophe
NAME_SIGNS = APOSTROPHES | frozenset(".,_@+")  # initials, "King, Jr.", and what earlier accounts' names held
JOINERS = frozenset("\u200c\u200d")  # zero-width (non-)joiners: part of Persian and Indic spellings
STUDENT_ID_SIGNS = frozenset("-._/")
NAME_RULE = "names are letters, digits, spaces, apostrophes, hyphens and . , _ @ +"
STUDENT_ID_RULE = "student ids are letters, digits and - . _ /"


def clean_name(text: str) -> str:
    """The name with its whitespace trimmed and collapsed, composed (NFC)."""
    name = unicodedata.normalize("NFC", " ".join(text.split()))
    if not name:
        raise ValueError("the name is empty")
    if len(name) > NAME_MAX:
        raise ValueError(f"the name {name[:20] + '…'!r} is too long: {len(name)} characters, {NAME_MAX} at most")
    odd = next((char for char in name if not _name_char(char)), None)
    if odd is not None:
        raise ValueError(f"the name {name!r} holds {describe(odd)}: {NAME_RULE}")
    if not (_category(name[0]) in "LN" or name[0] in APOSTROPHES):
        raise ValueError(f"the name {name!r} starts with {name[0]!r}: start it with a letter or a digit")
    if not any(_category(char) == "L" for char in name):
        raise ValueError(f"the name {name!r} holds no letter")
    return name


def clean_email(text: str) -> str | None:
    """The address with its domain normalised (lower case, IDNA), or None for an empty cell. Only the
    syntax is checked: the server sends no mail and looks nothing up."""
    text = text.strip()
    if not text:
        return None
    try:
        address = validate_email(text, check_deliverability=False).normalized
    except EmailNotValidError as error:
        raise ValueError(f"the email {text[:EMAIL_MAX]!r} is not an address: {error}") from None
    if len(address) > EMAIL_MAX:
        raise ValueError(f"the email {address[:20] + '…'!r} is too long: {EMAIL_MAX} characters at most")
    return address


def clean_student_id(text: str) -> str | None:
    """The id as given (trimmed), or None for an empty cell."""
    student_id = unicodedata.normalize("NFC", text.strip())
    if not student_id:
        return None
    if len(student_id) > STUDENT_ID_MAX:
        raise ValueError(f"the student id {student_id[:20] + '…'!r} is too long: {STUDENT_ID_MAX} characters at most")
    odd = next((char for char in student_id if _category(char) not in "LN" and char not in STUDENT_ID_SIGNS), None)
    if odd is not None:  # 1.23457E+11: a spreadsheet that took the id for a number
        raise ValueError(f"the student id {student_id!r} holds {describe(odd)}: {STUDENT_ID_RULE} "
                         "(format the column as text in the spreadsheet so that it keeps every digit)")
    if _category(student_id[0]) not in "LN":
        raise ValueError(f"the student id {student_id!r} starts with {student_id[0]!r}: "
                         "start it with a letter or a digit")
    return student_id


def identity_key(text: str) -> str:
    """How two spellings of one name or address compare: case-folded, composed."""
    return unicodedata.normalize("NFC", text.casefold())


def describe(char: str) -> str:
    """A character as an instructor can find it: 'é' or U+202E RIGHT-TO-LEFT OVERRIDE."""
    name = unicodedata.name(char, "")
    if char.isprintable() and char != " ":
        return repr(char)
    return f"U+{ord(char):04X}" + (f" {name}" if name else " (a control character)")


def _category(char: str) -> str:
    return unicodedata.category(char)[0]


def _name_char(char: str) -> bool:
    major = _category(char)
    return (major in "LMN" or char == " " or char in NAME_SIGNS or unicodedata.category(char) == "Pd"
            or char in JOINERS)

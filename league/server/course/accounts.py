"""What a person's fields may hold: a name, an email address, a student id, Canvas's ids.

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
CANVAS_ID_MAX = 64  # characters (the users.canvas_id column)
LOGIN_MAX = 254  # characters (the users.sis_login_id column: a login may be an address)
LOGIN_SIGNS = STUDENT_ID_SIGNS | frozenset("@+")
LOGIN_RULE = "SIS Login IDs are letters, digits and - . _ / @ +"


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
    return _clean_identifier(text, "student id", STUDENT_ID_MAX, STUDENT_ID_SIGNS, STUDENT_ID_RULE)


def clean_canvas_id(text: str) -> str | None:
    """A Canvas user ID (the ID column of Canvas's gradebook export: digits), or None for an empty cell."""
    canvas_id = text.strip()
    if canvas_id and not (canvas_id.isascii() and canvas_id.isdigit() and len(canvas_id) <= CANVAS_ID_MAX):
        raise ValueError(f"the Canvas ID {canvas_id[:20]!r} is not a Canvas user ID (digits, {CANVAS_ID_MAX} at "
                         "most): keep the ID column as Canvas exported it")
    return canvas_id or None


def clean_login(text: str) -> str | None:
    """A SIS Login ID (a username or an address, as the institution's Canvas has it), or None for an empty cell."""
    return _clean_identifier(text, "SIS Login ID", LOGIN_MAX, LOGIN_SIGNS, LOGIN_RULE)


def _clean_identifier(text: str, label: str, most: int, signs: frozenset[str], rule: str) -> str | None:
    identifier = unicodedata.normalize("NFC", text.strip())
    if not identifier:
        return None
    if len(identifier) > most:
        raise ValueError(f"the {label} {identifier[:20] + '…'!r} is too long: {most} characters at most")
    odd = next((char for char in identifier if _category(char) not in "LN" and char not in signs), None)
    if odd is not None:  # 1.23457E+11: a spreadsheet that took the id for a number
        raise ValueError(f"the {label} {identifier!r} holds {describe(odd)}: {rule} "
                         "(format the column as text in the spreadsheet so that it keeps every digit)")
    if _category(identifier[0]) not in "LN":
        raise ValueError(f"the {label} {identifier!r} starts with {identifier[0]!r}: "
                         "start it with a letter or a digit")
    return identifier


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

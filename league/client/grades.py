"""`league grades`: instructors, the grades as CSV (an assignment's or the course's, generic, Canvas or
Moodle) and the rubric; students, their own grade once published."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from league.client.api import Api, ClientError, connection
from league.client.assignments import find_assignment
from league.exit_codes import EXIT_ERROR, EXIT_OK


def run_grades(args: argparse.Namespace) -> int:
    """Instructors: the grades as CSV on standard output (an assignment's, or the course's); with
    --set-rubric, set the assignment's rubric (and say what changed); with --check, how Canvas will
    match the Canvas file's students. Students: their own grade, once published."""
    with Api(connection(args)) as api:
        me = api.get("/api/users/me")
        assignment = find_assignment(api, args.assignment) if args.assignment else None
        if me["role"] != "instructor":
            if assignment is None:
                raise ClientError("league grades ASSIGNMENT: which assignment?", EXIT_ERROR)
            return print_my_grade(api.get(f"/api/assignments/{assignment['id']}/grades/me"))
        if args.check and args.format != "canvas":
            raise ClientError("--check says how Canvas will match the file's students: league grades "
                              "[ASSIGNMENT] --format canvas --check", EXIT_ERROR)
        if args.set_rubric:
            if assignment is None:
                raise ClientError("league grades ASSIGNMENT --set-rubric FILE: which assignment?", EXIT_ERROR)
            saved = api.call("PUT", f"/api/assignments/{assignment['id']}/rubric",
                             json=read_rubric_file(args.set_rubric))
            print(rubric_change(assignment["name"], assignment["rubric"], saved["rubric"]))
            return EXIT_OK
        path = f"/api/assignments/{assignment['id']}/grades" if assignment else "/api/grades"
        if args.check:
            print(api.get(f"{path}/canvas-match")["summary"])
            return EXIT_OK
        sys.stdout.write(api.get(f"{path}.csv", format=args.format, identifier=args.identifier))
        sys.stdout.flush()
        if args.format == "moodle":
            warn_unidentified(api.get("/api/users"), args.identifier)
        elif args.format == "canvas":
            print(api.get(f"{path}/canvas-match")["summary"], file=sys.stderr)
    return EXIT_OK


def rubric_change(name: str, old: dict | None, new: dict) -> str:
    """What --set-rubric changed, in one line: the rubric before and after (compact JSON)."""
    def compact(rubric: dict | None) -> str:
        return json.dumps(rubric, separators=(",", ":")) if rubric else "none"

    if old == new:
        return f"{name}: rubric unchanged ({compact(new)})"
    return f"{name}: rubric set to {compact(new)} (was {compact(old)}); `league grades {name!r}` prints the grades"


def read_rubric_file(name: str) -> dict:
    text = sys.stdin.read() if name == "-" else Path(name).read_text(encoding="utf-8")
    try:
        return json.loads(text)
    except ValueError as error:
        raise ClientError(f"{name}: not JSON ({error}); see the server README, Grades, for examples",
                          EXIT_ERROR) from None


def warn_unidentified(users: list[dict], identifier: str) -> None:
    """Name the students the Moodle file leaves out: those without the identifier it matches by."""
    key = "email" if identifier == "email" else "student_id"
    missing = [u["name"] for u in users if u["role"] == "student" and not u.get(key)]
    if missing:
        print(f"left out of the Moodle file, without {'an email' if key == 'email' else 'a student id'}: "
              f"{', '.join(missing)} (upload the roster with that column, or use the other --identifier)",
              file=sys.stderr)


def print_my_grade(grade: dict) -> int:
    if grade["points"] is None:
        print(f"{grade['assignment']}: no grade yet ({grade['status']})")
        return EXIT_OK
    rank = f", rank {grade['rank']} of {grade['students']}" if grade["rank"] else ""
    late = f", late: x{grade['penalty']:g}" if grade["late"] else ""
    print(f"{grade['assignment']}: {grade['points']:g} / {grade['max_points']:g} points{rank}{late}")
    if grade.get("note"):  # its private result changed after the publication (a server before 0018: no key)
        print(f"  changed since the publication: {grade['note']}")
    return EXIT_OK


def add_commands(command) -> None:
    grades = command(
        "grades", "instructors: the grades as CSV (an assignment's or the course's); students: your grade",
        run_grades,
        "Instructors: an assignment's grades on its private tracks, as CSV on standard output: generic\n"
        "(every column), or the file Canvas's or Moodle's gradebook imports (see the server README,\n"
        "Grades); without ASSIGNMENT, the course's: a column for each assignment with a rubric.\n"
        "  league grades \"Time trial\" --set-rubric rubric.json     (set how it is graded)\n"
        "  league grades \"Time trial\" --format canvas --check      (how Canvas will match the students)\n"
        "  league grades \"Time trial\" --format canvas > canvas.csv\n"
        "  league grades --format moodle --identifier idnumber > moodle.csv\n"
        "Students: league grades ASSIGNMENT prints your grade once the assignment is published.")
    grades.add_argument("assignment", nargs="?", metavar="ASSIGNMENT", help="its name or id (default: the course)")
    grades.add_argument("--format", choices=["generic", "canvas", "moodle"], default="generic",
                        help="the CSV's layout (default generic)")
    grades.add_argument("--identifier", choices=["email", "idnumber"], default="email",
                        help="moodle: the column Moodle matches students by (default email)")
    grades.add_argument("--set-rubric", metavar="FILE",
                        help="set the assignment's rubric from a JSON file ('-': standard input) and say what changed")
    grades.add_argument("--check", action="store_true",
                        help="with --format canvas: say how many rows carry an id Canvas matches, instead of the file")

"""`league assignments` (list them with the user's due times; instructors: create, edit, extend,
publish) and `league select` (the submission that counts as the user's final one)."""
from __future__ import annotations

import argparse

from league.client.api import Api, ClientError, connection
from league.client.output import local_time, print_table
from league.exit_codes import EXIT_ERROR, EXIT_OK


def find_assignment(api: Api, wanted: str) -> dict:
    """The assignment `wanted` names (its name, any case, or its id)."""
    assignments = api.get("/api/assignments")
    found = [a for a in assignments if a["name"] == wanted or str(a["id"]) == wanted] or [
        a for a in assignments if a["name"].casefold() == wanted.casefold()]
    if len(found) == 1:
        return found[0]
    listing = ", ".join(a["name"] for a in assignments) or "none yet"
    raise ClientError(f"no assignment named {wanted!r}; the assignments: {listing}", EXIT_ERROR)


def time_left(until: str | None, now: str) -> str:
    """What is left to `until`, rounded down ("2d 3h 4m", "0h 5m"); the last minute is "under a
    minute", never "0h 0m" nor "passed" while uploads are still taken."""
    if not until:
        return "no deadline"
    from datetime import datetime

    seconds = (datetime.fromisoformat(until) - datetime.fromisoformat(now)).total_seconds()
    if seconds <= 0:
        return "passed"
    if seconds < 60:
        return "under a minute"
    days, rest = divmod(int(seconds), 86400)
    return f"{days}d {rest // 3600}h {rest % 3600 // 60}m" if days else f"{rest // 3600}h {rest % 3600 // 60}m"


def parse_time(text: str) -> str:
    """An ISO time given on the command line; without a zone, this machine's."""
    from datetime import datetime

    try:
        moment = datetime.fromisoformat(text)
    except ValueError:
        raise ClientError(f"{text!r} is not a time such as 2026-12-01T23:59 or 2026-12-01T23:59+01:00",
                          EXIT_ERROR) from None
    return (moment if moment.tzinfo else moment.astimezone()).isoformat()


def run_assignments(args: argparse.Namespace) -> int:
    with Api(connection(args)) as api:
        if args.action == "list":
            return list_assignments(api.get("/api/assignments"), args.csv)
        if not args.names:
            raise ClientError(f"league assignments {args.action} NAME: which assignment?", EXIT_ERROR)
        if args.action == "create":
            created = api.call("POST", "/api/assignments", json={"name": args.names[0], **assignment_fields(args)})
            print(f"assignment {created['id']}: {created['name']} created ({describe_times(created)}, "
                  f"{created['episodes']} episodes, public seed {created['seed']})")
            return EXIT_OK
        assignment = find_assignment(api, args.names[0])
        where = f"/api/assignments/{assignment['id']}"
        if args.action == "edit":
            fields = assignment_fields(args)
            if not fields:
                raise ClientError("league assignments edit NAME: say what to change (--due, --episodes, ...)",
                                  EXIT_ERROR)
            edited = api.call("PATCH", where, json=fields)
            print(f"{edited['name']}: {describe_changes(assignment, edited, fields)}")
        elif args.action == "publish":
            api.call("POST", f"{where}/publish")
            print(f"{assignment['name']}: published; its students see the private board (and their grades, once "
                  "it has a rubric)")
        elif args.action == "extend":
            if len(args.names) != 2 or not args.due:
                raise ClientError("league assignments extend NAME STUDENT --due TIME", EXIT_ERROR)
            student = [u for u in api.get("/api/users") if u["name"] == args.names[1]]
            if not student:
                raise ClientError(f"no student named {args.names[1]!r} in your course", EXIT_ERROR)
            extension = api.call("PUT", f"{where}/extensions/{student[0]['id']}", json={"due_at": parse_time(args.due)})
            print(f"{assignment['name']}: {student[0]['name']} is now due {local_time(extension['due_at'])} "
                  f"(the assignment's due time: {local_time(assignment['due_at']) or 'none'})")
    return EXIT_OK


TIME_FIELDS = {"opens_at": "opens", "due_at": "due", "late_until": "late until"}


def describe_times(a: dict) -> str:
    """An assignment's times in this machine's zone: "opens ..., due ..., late until ..."."""
    times = [f"{label} {local_time(a[name])}" for name, label in TIME_FIELDS.items() if a.get(name)]
    return ", ".join(times) or "no due time"


def describe_changes(before: dict, after: dict, fields: dict) -> str:
    """What an edit changed, field by field as the server stored it: "due 2026-12-01 23:59 CET (was ...)"."""
    changes = []
    for name in fields:
        old, new = before.get(name), after.get(name)
        if name in TIME_FIELDS:
            label, old, new = TIME_FIELDS[name], local_time(old) or "none", local_time(new) or "none"
        else:
            label = name.replace("_", " ")
        changes.append(f"{label} {new}" + (f" (was {old})" if old != new else " (unchanged)"))
    return "; ".join(changes)


def assignment_fields(args: argparse.Namespace) -> dict:
    fields = {"description": args.description, "seed": args.seed, "episodes": args.episodes,
              "late_penalty": args.late_penalty, "daily_quota": args.daily_quota, "auto_publish": args.auto_publish,
              "keep_open": args.keep_open}
    for name, text in (("opens_at", args.opens), ("due_at", args.due), ("late_until", args.late_until)):
        if text is not None:
            fields[name] = parse_time(text)
    return {name: value for name, value in fields.items() if value is not None}


def list_assignments(assignments: list[dict], as_csv: bool) -> int:
    rows = []
    for a in assignments:
        final = a.get("final") or {}
        mine = f"{final.get('submission_id') or ''}{' (selected)' if final.get('selected') else ''}"
        automatic = f" (automatic{', kept open' if a.get('keep_open') else ''})" if a.get("automatic") else ""
        rows.append([a["id"], a["name"] + automatic, a["state"], local_time(a["opens_at"]),
                     local_time(a["my_due_at"]) + (" (extension)" if a["extended"] else ""),
                     upload_time_left(a), local_time(a["late_until"]), mine,
                     "yes" if a["published_at"] else "no"])
    print_table(["id", "assignment", "state", "opens", "due (yours)", "time left", "late until", "final",
                 "published"], rows, as_csv)
    return EXIT_OK


def upload_time_left(a: dict) -> str:
    """The time left to upload: to the due time, then (state late) to the late window's end."""
    if a["state"] == "closed":
        return "closed"
    if a["state"] == "late":
        return f"late window: {time_left(a['my_closes_at'], a['now'])}"
    return time_left(a["my_due_at"], a["now"])


def run_select(args: argparse.Namespace) -> int:
    with Api(connection(args)) as api:
        if args.assignment:
            assignment_id = find_assignment(api, args.assignment)["id"]
        else:
            assignment_id = api.get(f"/api/submissions/{args.submission}")["assignment_id"]
        answer = api.call("POST", f"/api/assignments/{assignment_id}/selection",
                          json={"submission_id": args.submission})
    print(f"{answer['name']}: your final submission is {answer['final']['submission_id']} (until "
          f"{local_time(answer['my_closes_at']) or 'no deadline'})")
    return EXIT_OK


def add_commands(command) -> None:
    assignments = command(
        "assignments", "list the course's assignments with your due times; instructors: create, edit, extend, publish",
        run_assignments,
        "Without an action: each assignment, its state for you (upcoming, open, late, closed), when it opens,\n"
        "your due time (an extension if you have one) in this machine's time zone, the time left, the late\n"
        "window's end, your final submission (the one you selected, else your best on the public board),\n"
        "and whether its private results are published. Instructors:\n"
        "  league assignments create NAME --due 2026-12-01T23:59 [--opens T] [--late-until T --late-penalty 0.5]\n"
        "                             [--episodes 20] [--seed 0] [--daily-quota 5] [--auto-publish]\n"
        "  league assignments edit NAME [any of those options]\n"
        "  league assignments extend NAME STUDENT --due T     (that student's own due time)\n"
        "  league assignments publish NAME                    (show the private board to the students)\n"
        "  league assignments edit default --keep-open        (the automatic assignment stays open beside yours)\n"
        "Times without a zone are this machine's.")
    assignments.add_argument("action", nargs="?", default="list",
                             choices=["list", "create", "edit", "extend", "publish"])
    assignments.add_argument("names", nargs="*", metavar="NAME", help="the assignment (extend: and the student)")
    assignments.add_argument("--description")
    assignments.add_argument("--seed", type=int, help="the public tracks' seed")
    assignments.add_argument("--episodes", type=int, help="episodes of each evaluation (public and private)")
    assignments.add_argument("--opens", metavar="TIME", help="uploads open (ISO time)")
    assignments.add_argument("--due", metavar="TIME", help="the due time (ISO time)")
    assignments.add_argument("--late-until", metavar="TIME", help="late uploads are taken until then")
    assignments.add_argument("--late-penalty", type=float, metavar="FACTOR", help="a late final's score factor")
    assignments.add_argument("--daily-quota", type=int, metavar="N", help="uploads per student per UTC day")
    assignments.add_argument("--auto-publish", action="store_true", default=None,
                             help="publish the private board once every final is evaluated")
    assignments.add_argument("--keep-open", action=argparse.BooleanOptionalAction, default=None,
                             help="edit default: the course's automatic assignment keeps taking uploads beside the "
                                  "course's own assignments (by default it closes once there is one)")
    assignments.add_argument("--csv", action="store_true", help="print the list as CSV")

    select = command("select", "choose the submission that counts as your final one in its assignment", run_select,
                     "Your final submission is evaluated on the assignment's private tracks at your due time;\n"
                     "without a selection it is your best on the public board.")
    select.add_argument("submission", type=int, metavar="SUBMISSION", help="the submission's id")
    select.add_argument("--assignment", metavar="NAME", help="default: the submission's assignment")

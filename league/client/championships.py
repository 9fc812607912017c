"""`league standings` and `league championships`: the console's championship panel from a terminal
(list, create, run a round and watch it, standings)."""
from __future__ import annotations

import argparse
import sys
import time

from league.client.api import Api, ClientError, connection, poll_delays
from league.client.assignments import find_assignment
from league.client.output import local_time, print_table
from league.command import add_env_switches, env_options
from league.exit_codes import EXIT_ERROR, EXIT_OK, EXIT_REJECTED, EXIT_TIMEOUT
from league.championship import DEFAULT_POINTS
from league.statuses import ENDED, FAILED


def run_standings(args: argparse.Namespace) -> int:
    with Api(connection(args, need_token=args.csv)) as api:
        championship = championship_id(api, args.championship)
        if args.csv:  # instructors: the grades
            sys.stdout.write(api.get(f"/api/championships/{championship}/standings.csv"))
            return EXIT_OK
        rows = api.get(f"/api/championships/{championship}/standings", size=100)["items"]
    print_table(["rank", "student", "agent", "id", "points", "wins", "heats", "rating"],
                [[r["rank"], r["owner"], r["name"], r["submission_id"], r["points"], r["wins"], len(r["finishes"]),
                  f"{r['rating']:.2f}"] for r in rows], False)
    return EXIT_OK


def run_championships(args: argparse.Namespace) -> int:
    """The console's championship panel from a terminal: list, create, run a round and watch it, standings."""
    if args.action == "list":
        with Api(connection(args)) as api:
            championships = api.get("/api/championships")
        print_table(["id", "championship", "rounds", "cars per heat", "assignment", "baselines"],
                    [[c["id"], c["name"], len(c["rounds"]), c["heat_size"], c["assignment_id"] or "",
                      "yes" if c["include_baselines"] else "no"] for c in championships], args.csv)
        return EXIT_OK
    if not args.championship:
        raise ClientError(f"league championships {args.action} CHAMPIONSHIP: which championship?", EXIT_ERROR)
    if args.action == "standings":
        return run_standings(args)
    with Api(connection(args)) as api:
        if args.action == "create":
            return create_championship(api, args)
        championship = championship_id(api, args.championship)
        if args.run_round:
            started = api.call("POST", f"/api/championships/{championship}/rounds")
            print(f"round {started['number']} started: {started['heats_total']} heats", file=sys.stderr)
            if args.no_wait:
                print(started["number"])
                return EXIT_OK
            watched = watch_round(api, championship, started["number"], args.timeout, progress=not args.no_progress)
            return report_round(watched)
        rounds = api.get(f"/api/championships/{championship}")["rounds"]
    print_table(["round", "status", "heats done", "races", "created"],
                [[r["number"], r["status"], f"{r['heats_done']}/{r['heats_total']}",
                  " ".join(str(i) for i in r["race_ids"]), local_time(r["created_at"])] for r in rounds], args.csv)
    return EXIT_OK


def create_championship(api: Api, args: argparse.Namespace) -> int:
    body = {"name": args.championship, "include_baselines": not args.no_baselines, "env_options": env_options(args)}
    for field, value in (("heat_size", args.heat_size), ("seed", args.seed), ("points", args.points)):
        if value is not None:
            body[field] = value
    if args.assignment:
        body["assignment"] = find_assignment(api, args.assignment)["id"]
    created = api.call("POST", "/api/championships", json=body)
    print(f"championship {created['id']}: {created['name']} created "
          f"(league championships rounds {created['id']} --run races its first round)", file=sys.stderr)
    print(created["id"])
    return EXIT_OK


def watch_round(api: Api, championship: int, number: int, timeout: float, progress: bool = True) -> dict:
    """Poll a round until it is over (done or failed), with a bar of its heats done."""
    from tqdm import tqdm

    deadline, delays = time.monotonic() + timeout, poll_delays()
    path = f"/api/championships/{championship}/rounds/{number}"
    with tqdm(total=None, disable=not progress, file=sys.stderr, unit="heat",
              bar_format="{desc} {bar} {n}/{total} heats") as bar:
        while True:
            round_ = api.get(path)
            bar.total = round_["heats_total"]
            bar.set_description_str(f"round {number}: {round_['status']}")
            bar.update(round_["heats_done"] - bar.n)
            if round_["status"] in ENDED:
                return round_
            if time.monotonic() > deadline:
                raise ClientError(f"round {number} is still {round_['status']} after {timeout:g} s "
                                  f"({round_['heats_done']}/{round_['heats_total']} heats done); follow it with "
                                  f"`league championships rounds {championship}`", EXIT_TIMEOUT)
            time.sleep(next(delays))


def report_round(round_: dict) -> int:
    heats = f"{round_['heats_done']}/{round_['heats_total']} heats done"
    if round_["status"] == FAILED:
        print(f"round {round_['number']} failed ({heats}): the instructor console's Jobs table says why")
        return EXIT_REJECTED
    print(f"round {round_['number']} is over ({heats}); races {' '.join(str(i) for i in round_['race_ids'])}")
    return EXIT_OK


def points_table(text: str) -> list[int]:
    try:
        return [int(part) for part in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: whole numbers separated by commas, e.g. 25,18,15") from None


def championship_id(api: Api, wanted: str) -> int:
    """The id of the championship `wanted` names: its id (digits) or its name (any case)."""
    if wanted.isdigit():
        return int(wanted)
    championships = api.get("/api/championships")
    found = [c for c in championships if c["name"] == wanted] or [
        c for c in championships if c["name"].casefold() == wanted.casefold()]
    if len(found) == 1:
        return found[0]["id"]
    listing = ", ".join(f"{c['id']} ({c['name']})" for c in championships) or "none yet"
    if found:
        raise ClientError(f"{len(found)} championships are named {wanted!r}: give the id of one of "
                          f"{', '.join(str(c['id']) for c in found)}", EXIT_ERROR)
    raise ClientError(f"no championship named {wanted!r}; the championships: {listing}", EXIT_ERROR)


def add_commands(command) -> None:
    standings = command("standings", "print a championship's standings", run_standings)
    standings.add_argument("championship", metavar="CHAMPIONSHIP",
                           help="the championship's name (quoted if it has spaces) or its id")
    standings.add_argument("--csv", action="store_true", help="instructors: the grades, as CSV")

    championships = command(
        "championships", "championships: list them; instructors: create one, run a round and watch it",
        run_championships,
        "Without an action: the course's championships. Then, as on the instructor console:\n"
        "  league championships create NAME [--heat-size 10] [--points 25,18,15] [--seed S]\n"
        "                               [--assignment NAME] [--no-baselines] [--no-obstacles ...]\n"
        "  league championships rounds CHAMPIONSHIP          (its rounds: status, heats done, races)\n"
        "  league championships rounds CHAMPIONSHIP --run    (race the next round, and watch it to the end)\n"
        "  league championships standings CHAMPIONSHIP [--csv]\n"
        "CHAMPIONSHIP: its id or its name (quoted if it has spaces).")
    championships.add_argument("action", nargs="?", default="list", choices=["list", "create", "rounds", "standings"])
    championships.add_argument("championship", nargs="?", metavar="CHAMPIONSHIP",
                               help="its id or name (create: the new one's name)")
    created = championships.add_argument_group("create")
    created.add_argument("--heat-size", type=int, metavar="N", help="cars per heat (default 10)")
    created.add_argument("--points", type=points_table, metavar="P1,P2,...",
                         help=f"points by finishing position in a heat (default {','.join(map(str, DEFAULT_POINTS))})")
    created.add_argument("--seed", type=int, help="draws the heats (default: drawn by the server)")
    created.add_argument("--assignment", metavar="NAME",
                         help="race each student's final submission of this assignment (default: active ones)")
    created.add_argument("--no-baselines", action="store_true", help="the bundled baselines do not race")
    add_env_switches(created)
    rounds = championships.add_argument_group("rounds")
    rounds.add_argument("--run", dest="run_round", action="store_true",  # (`run`: the command's function)
                        help="start the next round and watch it to the end")
    rounds.add_argument("--no-wait", action="store_true", help="with --run: print the round's number once started")
    rounds.add_argument("--timeout", type=float, default=3600, help="seconds --run watches at most (default 3600)")
    rounds.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    championships.add_argument("--csv", action="store_true", help="print CSV (standings: instructors, the grades)")

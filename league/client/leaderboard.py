"""`league leaderboard`: the course's board, or an assignment's (public or private); instructors: the grades as CSV."""
from __future__ import annotations

import argparse
import sys

from league.client.api import Api, connection
from league.client.assignments import find_assignment
from league.client.output import print_table
from league.exit_codes import EXIT_OK


def run_leaderboard(args: argparse.Namespace) -> int:
    with Api(connection(args, need_token=args.csv or bool(args.assignment))) as api:
        path = "/api/leaderboard"
        params = {}
        if args.assignment:
            path = f"/api/assignments/{find_assignment(api, args.assignment)['id']}/board"
            params = {"board": "private" if args.private else "public"}
        if args.csv:  # instructors: the grades
            sys.stdout.write(api.get(f"{path}.csv", **params))
            return EXIT_OK
        rows = api.get(path, size=100, **params)["items"]
    print_table(["rank", "student", "agent", "id", "completed", "mean return", "mean speed", "rating"],
                [["stale" if r.get("stale") else r["rank"], r["owner"], r["name"], r["submission_id"],
                  f"{r['completed']}/{r['episodes']}",
                  f"{r['mean_return']:.3f}", f"{r['mean_speed']:.3f}",
                  "" if r["rating"] is None else f"{r['rating']:.2f}"] for r in rows], False)
    return EXIT_OK


def add_commands(command) -> None:
    board = command("leaderboard", "print the course leaderboard (or an assignment's board)", run_leaderboard)
    board.add_argument("--csv", action="store_true", help="instructors: the grades, as CSV")
    board.add_argument("--assignment", metavar="NAME", help="that assignment's board (default: the default one's)")
    board.add_argument("--private", action="store_true",
                       help="with --assignment: the private board (once published; instructors: always)")

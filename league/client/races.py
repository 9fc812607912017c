"""`league race-server`: a friendly race of submissions on the server, its classification printed
(and its replay saved, for `league replay`)."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from league.client.api import Api, ClientError, connection, poll_delays
from league.exit_codes import EXIT_OK, EXIT_REJECTED, EXIT_TIMEOUT
from league.statuses import ENDED, FAILED


def run_race_server(args: argparse.Namespace) -> int:
    body = {"submission_ids": args.ids, **({"seed": args.seed} if args.seed is not None else {})}
    with Api(connection(args)) as api:
        created = api.call("POST", "/api/races", json=body)
        print(f"race {created['id']}: {api.conn.server}/races/{created['id']}", file=sys.stderr)
        deadline, delays = time.monotonic() + args.timeout, poll_delays()
        race = api.get(f"/api/races/{created['id']}")
        while race["status"] not in ENDED:
            if time.monotonic() > deadline:
                raise ClientError(f"race {created['id']} is still {race['status']} after {args.timeout:g} s",
                                  EXIT_TIMEOUT)
            time.sleep(next(delays))
            race = api.get(f"/api/races/{created['id']}")
        if race["status"] == FAILED:
            print(f"race {race['id']} failed: {race['error']}")
            return EXIT_REJECTED
        if args.replay:
            Path(args.replay).write_text(json.dumps(api.get(f"/api/races/{race['id']}/replay")))
    from league.evaluation import classification_table

    rows = [{**row, "name": f"{row['name']} ({row['owner']})"} for row in race["classification"]]  # as the replay
    print(f"race {race['id']} on seed {race['seed']}\n{classification_table(rows)}")
    return EXIT_OK


def add_commands(command) -> None:
    race = command("race-server", "race submissions on the server (a friendly race) and print the classification",
                   run_race_server)
    race.add_argument("ids", type=int, nargs="+", metavar="SUB_ID", help="submission ids (yours first)")
    race.add_argument("--seed", type=int, help="the track's seed (default: drawn by the server)")
    race.add_argument("--replay", metavar="FILE", help="save the race's replay (JSON) for `league replay`")
    race.add_argument("--timeout", type=float, default=600, help="seconds to wait for the race (default 600)")

"""The instructor console's tools from a terminal: `league integrity`, `jobs`, `audit`, `rerun` and
`privacy` (who sees the course's boards: anyone may ask, instructors change it)."""
from __future__ import annotations

import argparse
import json
import sys

from league.client.api import Api, ClientError, connection
from league.client.output import local_time, print_table
from league.exit_codes import EXIT_ERROR, EXIT_OK
from league.statuses import JOB_STATUSES


def run_integrity(args: argparse.Namespace) -> int:
    with Api(connection(args)) as api:
        if args.probe:
            queued = api.call("POST", "/api/integrity/probe")["queued"]
            print(f"{len(queued)} submissions queued to be probed (low priority)", file=sys.stderr)
            return EXIT_OK
        if args.csv:
            sys.stdout.write(api.get("/api/integrity.csv"))
            return EXIT_OK
        report = api.get("/api/integrity")
    print_table(["group", "kind", "distance", "owner", "id", "agent", "file"],
                [[number, group["kind"] + (f" ({group['baseline']})" if group["baseline"] else ""),
                  "" if group["distance"] is None else f"{group['distance']:.1e}", s["owner"], s["id"], s["name"],
                  s["kind"]] for number, group in enumerate(report["groups"], 1) for s in group["submissions"]],
                False)
    if report["not_compared"]:
        print(f"{len(report['not_compared'])} submissions not compared on every probe set (not yet probed, or "
              "failed on one): `league integrity --probe` probes those not yet probed", file=sys.stderr)
    return EXIT_OK


def run_jobs(args: argparse.Namespace) -> int:
    """Instructors: the course's latest jobs (the console's Jobs tab), or cancel one."""
    with Api(connection(args)) as api:
        if args.cancel is not None:
            job = api.call("POST", f"/api/jobs/{args.cancel}/cancel")
            print(f"job {job['id']} ({job['kind']}) cancelled: {job['status']}", file=sys.stderr)
            return EXIT_OK
        jobs = api.get("/api/jobs", limit=args.limit, **({"status": args.status} if args.status else {}))
    print_table(["id", "kind", "status", "submission", "race", "attempts", "created", "error"],
                [[j["id"], j["kind"], j["status"], j["submission_id"] or "", j["race_id"] or "", j["attempts"],
                  local_time(j["created_at"]), (j["error"] or "")[:80]] for j in jobs], args.csv)
    return EXIT_OK


def run_audit(args: argparse.Namespace) -> int:
    """Instructors: the audit log, newest first (the console's Audit tab)."""
    with Api(connection(args)) as api:
        if args.csv:
            sys.stdout.write(api.get("/api/audit.csv"))
            return EXIT_OK
        page = api.get("/api/audit", page=args.page, size=args.size)
    print_table(["at", "who", "action", "target", "details"],
                [[local_time(e["at"]), e["actor_name"], e["action"], f"{e['target_kind']} {e['target_id'] or ''}",
                  json.dumps(e["details"], separators=(",", ":"))[:120]] for e in page["items"]], False)
    return EXIT_OK


def run_rerun(args: argparse.Namespace) -> int:
    """Instructors: evaluate a submission again, or every ready one of the course (the console's Re-run)."""
    if (args.submission is None) == (not args.all):
        raise ClientError("league rerun: give a SUBMISSION id or --all", EXIT_ERROR)
    with Api(connection(args)) as api:
        body = {"all": True} if args.all else {"submission_id": args.submission}
        queued = api.call("POST", "/api/evaluations/rerun", json=body)["queued"]
    print(f"{len(queued)} evaluation{'s' if len(queued) != 1 else ''} queued again"
          + (f": submissions {', '.join(map(str, queued))}" if queued else ""), file=sys.stderr)
    return EXIT_OK


def run_privacy(args: argparse.Namespace) -> int:
    """Who sees the course's boards; instructors change it (the console's Privacy panel)."""
    with Api(connection(args)) as api:
        before = api.get("/api/settings/privacy")["board_visibility"]
        if args.board_visibility is None:
            print(before)
            return EXIT_OK
        after = api.call("PUT", "/api/settings/privacy", json={"board_visibility": args.board_visibility})
    after = after["board_visibility"]
    print(f"board visibility: {after}" + (f" (was {before})" if after != before else " (unchanged)"), file=sys.stderr)
    return EXIT_OK


def add_commands(command) -> None:
    integrity = command("integrity", "instructors: print the integrity report (submissions that look copied)",
                        run_integrity,
                        "Submissions of different students with the same file, or alike actions on the league's "
                        "probe sets (public, and the assignment's secret one) up to a rescaling or offset, and "
                        "copies of the bundled baselines: one line per submission of each group. Nothing is "
                        "blocked.")
    integrity.add_argument("--csv", action="store_true", help="print the report as CSV")
    integrity.add_argument("--probe", action="store_true",
                           help="queue the submissions not yet probed to be probed, then run the report again")

    jobs = command("jobs", "instructors: the course's latest jobs (validations, evaluations, races); cancel one",
                   run_jobs)
    jobs.add_argument("--status", choices=JOB_STATUSES, help="only jobs of this status")
    jobs.add_argument("--limit", type=int, default=100, help="how many, newest first (default 100, at most 1000)")
    jobs.add_argument("--cancel", type=int, metavar="JOB", help="cancel this queued or running job")
    jobs.add_argument("--csv", action="store_true", help="print CSV")

    audit = command("audit", "instructors: the audit log, newest first (who changed what, with before and after)",
                    run_audit)
    audit.add_argument("--page", type=int, default=1, help="1-based page (default 1)")
    audit.add_argument("--size", type=int, default=50, help="events a page (default 50, at most 100)")
    audit.add_argument("--csv", action="store_true", help="the whole log as CSV")

    rerun = command("rerun", "instructors: evaluate a submission again, or every ready one of the course", run_rerun)
    rerun.add_argument("submission", nargs="?", type=int, metavar="SUBMISSION", help="the submission's id")
    rerun.add_argument("--all", action="store_true", help="every ready submission of the course (baselines too)")

    privacy = command("privacy", "who sees the course's boards; instructors: --board-visibility changes it",
                      run_privacy)
    privacy.add_argument("--board-visibility", choices=["public", "members", "instructors"],
                         help="public (anyone, under display names or pseudonyms), members (the course's "
                              "logged-in users) or instructors")

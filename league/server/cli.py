"""The server's commands of the `league` CLI: serve, worker, users.

league/cli.py calls `add_commands(subparsers)`; each command is run as `args.run(args)` and
returns the exit status. `python -m league.server ...` runs the same commands.
"""
from __future__ import annotations

import argparse
import ctypes
import logging
import os
import signal
import subprocess
import sys

from league.server.config import Settings
from league.server.db.models import INSTRUCTOR, STUDENT

log = logging.getLogger("league.server")
PR_SET_PDEATHSIG = 1  # prctl(2)


def add_commands(subparsers) -> None:
    serve = subparsers.add_parser("serve", help="run the league server: the API and a worker",
                                  description="Run the API (OpenAPI docs at /docs) and, unless --no-worker, a "
                                              "`league worker` as its child process (stopped with it). Settings "
                                              "come from LEAGUE_* variables and .env (see league/server/config.py).")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    serve.add_argument("--no-worker", action="store_true", help="API only: jobs are run by `league worker`s")
    serve.add_argument("--threads", type=int, help="jobs its worker runs at once")
    serve.set_defaults(run=run_serve)

    worker = subparsers.add_parser("worker", help="run a worker (more of them: on this or other machines)",
                                   description="Run jobs from the queue until interrupted. Point "
                                               "LEAGUE_DATABASE_URL and LEAGUE_QUEUE_URL at the shared "
                                               "PostgreSQL and Redis to work for a remote server.")
    worker.add_argument("--threads", type=int, help="jobs run at once (default LEAGUE_WORKER_THREADS)")
    worker.add_argument("--cpus", help="run on these CPUs only, e.g. 1 or 0-3,6 (default LEAGUE_WORKER_CPUS: all); "
                                       "the sandboxes it starts inherit them. Not needed to share a machine: "
                                       "the workers of one machine split its CPUs by themselves "
                                       "(LEAGUE_CPU_SLOTS_DIR)")
    worker.set_defaults(run=run_worker)

    users = subparsers.add_parser("users", help="manage accounts")
    commands = users.add_subparsers(dest="users_command", required=True, metavar="{add,import,list,revoke}")
    add = commands.add_parser("add", help="add an account and print its API token")
    add.add_argument("name")
    add.add_argument("--role", choices=[INSTRUCTOR, STUDENT], default=STUDENT, help="default: student")
    add.add_argument("--email", help="the student's email address (optional)")
    add.add_argument("--student-id", help="the school's id of the student, unique in the course (optional)")
    add.set_defaults(run=run_users_add)
    roster = commands.add_parser(
        "import", help="create the students of a roster (CSV) and print their tokens as CSV",
        description="Create the students of a roster as spreadsheets export it: comma-, semicolon- or "
                    "tab-separated, with a header naming the columns (name, or first name and last name; email; "
                    "student id; in common spellings) or one name a line. Students enrolled already are skipped "
                    "(matched by student id or email, else by name); each bad line is reported with its number "
                    "and the others are created. Writes name,email,student_id,token of the new students to "
                    "standard output (tokens are shown once: redirect it to a file); exits 1 if a line had an error.")
    roster.add_argument("file", help="the roster, e.g. roster.csv (UTF-8, as Excel's 'CSV UTF-8' saves it)")
    roster.set_defaults(run=run_users_import)
    listing = commands.add_parser("list", help="list the accounts")
    listing.set_defaults(run=run_users_list)
    revoke = commands.add_parser("revoke", help="revoke an account (its token stops working)")
    revoke.add_argument("name")
    revoke.set_defaults(run=run_users_revoke)


def _logging() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")


def run_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from league.server.api.connections import connection_limits, uvicorn_protocols
    from league.server.app import create_app, open_league, prepare_league

    _logging()
    settings = Settings()
    protocols = uvicorn_protocols(connection_limits(settings))
    league_ = open_league(settings)
    prepare_league(league_)
    worker = None if args.no_worker else start_child_worker(args.threads)
    # uvicorn raises the SIGTERM or SIGINT it stopped on again once it is done: end here, not die there
    signal.signal(signal.SIGTERM, _exit_on_signal)
    try:
        uvicorn.run(create_app(settings, league_), host=args.host, port=args.port, log_level="info",
                    **protocols)
    except KeyboardInterrupt:
        pass
    finally:
        if worker is not None:
            stop_child_worker(worker)
    return 0


def _exit_on_signal(signum, frame) -> None:
    raise SystemExit(0)


def start_child_worker(threads: int | None) -> subprocess.Popen:
    """`league worker` as a child process: jobs never share the API's GIL. It gets SIGTERM (hands its
    jobs back, stops its sandboxes) when we stop, and also if we die (PR_SET_PDEATHSIG); in a session
    of its own, so a Ctrl-C reaches only us and we stop it at once instead of waiting for its jobs."""
    prctl, parent = ctypes.CDLL(None, use_errno=True).prctl, os.getpid()  # resolved before the fork

    def die_with_parent() -> None:
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # we died before prctl
            os.kill(os.getpid(), signal.SIGTERM)

    command = [sys.executable, "-m", "league.server", "worker", *(["--threads", str(threads)] if threads else [])]
    worker = subprocess.Popen(command, preexec_fn=die_with_parent, start_new_session=True)
    log.info("serve: worker process %d started", worker.pid)
    return worker


def stop_child_worker(worker: subprocess.Popen, timeout_s: float = 30) -> None:
    worker.terminate()
    try:
        worker.wait(timeout_s)
    except subprocess.TimeoutExpired:
        log.warning("serve: worker process %d did not stop in %g s: killed", worker.pid, timeout_s)
        worker.kill()
        worker.wait()


def run_worker(args: argparse.Namespace) -> int:
    from league.server.jobs.runner import lower_session_priority
    from league.server.jobs.worker import Worker, pin_to_cpus, worker_context

    _logging()
    settings = Settings()
    cpus = args.cpus if args.cpus is not None else settings.worker_cpus
    if cpus:
        try:
            log.info("worker: running on CPUs %s", ",".join(map(str, sorted(pin_to_cpus(cpus)))))
        except ValueError as error:
            print(f"league worker: --cpus {cpus!r}: {error}", file=sys.stderr)
            return 2
    lower_session_priority(settings.job_nice)
    context = worker_context(settings)
    log.info("worker: database %s, queue %s", context.sessions.kw["bind"].url.render_as_string(),
             type(context.queue.huey).__name__)
    Worker(context, threads=args.threads or settings.worker_threads).run_forever()
    return 0


def _sessions():
    from league.server.app import open_league
    from league.server.bootstrap import ensure_course
    from league.server.db.session import migrate

    settings = Settings()
    league_ = open_league(settings)
    migrate(league_.engine)
    ensure_course(league_.sessions, settings)
    return league_.sessions


def run_users_add(args: argparse.Namespace) -> int:
    from league.server.db import crud

    with _sessions().begin() as session:
        try:
            user, token = crud.create_user(session, name=args.name, role=args.role, course=crud.first_course(session),
                                           email=args.email, student_id=args.student_id)
        except crud.InvalidAccount as error:
            print(f"league: error: {error}", file=sys.stderr)
            return 1
        print(token)
    print(f"created {args.role} {user.name!r} (id {user.id}); the token above is shown once", file=sys.stderr)
    return 0


def run_users_import(args: argparse.Namespace) -> int:
    from league.server.db import crud
    from league.server.roster import MAX_ROSTER_BYTES, RosterError, import_roster, read_roster
    from league.spreadsheet import csv_text

    try:
        with open(args.file, "rb") as file:
            roster = read_roster(file.read(MAX_ROSTER_BYTES + 1))
    except (OSError, RosterError) as error:
        print(f"league: error: {args.file}: {error}", file=sys.stderr)
        return 1
    with _sessions().begin() as session:
        report = import_roster(session, course=crud.first_course(session), created_by=None, roster=roster)
        tokens = csv_text(["name", "email", "student_id", "token"],
                          ([user.name, user.email, user.student_id, token] for user, token in report.created))
    sys.stdout.write(tokens)  # once committed
    for problem in report.skipped:
        print(f"line {problem.line}: skipped {problem.name}: {problem.reason}", file=sys.stderr)
    for problem in report.errors:
        print(f"line {problem.line}: error: {problem.reason}", file=sys.stderr)
    print(f"created {_count(len(report.created), 'student')}, skipped {_count(len(report.skipped), 'line')}, "
          f"{_count(len(report.errors), 'line')} with errors; the tokens above are shown once", file=sys.stderr)
    return 1 if report.errors else 0


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def run_users_list(args: argparse.Namespace) -> int:
    from sqlalchemy import select

    from league.server.db.models import User

    with _sessions()() as session:
        for user in session.scalars(select(User).order_by(User.id)):
            state = "active" if user.active else "revoked"
            print(f"{user.id:>5}  {user.name:<30} {user.role:<10} {state}")
    return 0


def run_users_revoke(args: argparse.Namespace) -> int:
    from league.server.db import crud

    with _sessions().begin() as session:
        user = crud.user_by_name(session, name=args.name)
        if user is None:
            print(f"league: error: no user {args.name!r}", file=sys.stderr)
            return 1
        crud.revoke_user(session, user=user)
    print(f"revoked {args.name!r}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m league.server", description="MicroRacer League server")
    add_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.run(args)

"""The server's commands of the `league` CLI: serve, worker, users.

league/cli.py calls `add_commands(subparsers)`; each command is run as `args.run(args)` and
returns the exit status. `python -m league.server ...` runs the same commands.
"""
from __future__ import annotations

import argparse
import logging
import sys

from league.server.config import Settings
from league.server.db.models import INSTRUCTOR, STUDENT

log = logging.getLogger("league.server")


def add_commands(subparsers) -> None:
    serve = subparsers.add_parser("serve", help="run the league server: the API and an embedded worker",
                                  description="Run the API (OpenAPI docs at /docs) and, unless --no-worker, a "
                                              "worker in the same process. Settings come from LEAGUE_* "
                                              "variables and .env (see league/server/config.py).")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    serve.add_argument("--no-worker", action="store_true", help="API only: jobs are run by `league worker`s")
    serve.add_argument("--threads", type=int, help="jobs the embedded worker runs at once")
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
    commands = users.add_subparsers(dest="users_command", required=True, metavar="{add,list,revoke}")
    add = commands.add_parser("add", help="add an account and print its API token")
    add.add_argument("name")
    add.add_argument("--role", choices=[INSTRUCTOR, STUDENT], default=STUDENT, help="default: student")
    add.set_defaults(run=run_users_add)
    listing = commands.add_parser("list", help="list the accounts")
    listing.set_defaults(run=run_users_list)
    revoke = commands.add_parser("revoke", help="revoke an account (its token stops working)")
    revoke.add_argument("name")
    revoke.set_defaults(run=run_users_revoke)


def _logging() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")


def run_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from league.server.app import create_app, open_league, prepare_league
    from league.server.jobs.handlers import HANDLERS
    from league.server.jobs.runner import WorkerContext
    from league.server.jobs.worker import Worker

    _logging()
    settings = Settings()
    league_ = open_league(settings)
    prepare_league(league_)
    worker = None
    if not args.no_worker:
        context = WorkerContext(settings, league_.sessions, league_.queue, league_.store, HANDLERS)
        worker = Worker(context, threads=args.threads or settings.worker_threads, embedded=True)
        worker.start()
    try:
        uvicorn.run(create_app(settings, league_), host=args.host, port=args.port, log_level="info")
    finally:
        if worker is not None:
            worker.stop()
    return 0


def run_worker(args: argparse.Namespace) -> int:
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
    context = worker_context(settings)
    log.info("worker: database %s, queue %s", context.sessions.kw["bind"].url.render_as_string(),
             type(context.queue.huey).__name__)
    Worker(context, threads=args.threads or settings.worker_threads, embedded=False).run_forever()
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
            user, token = crud.create_user(session, name=args.name, role=args.role,
                                           course=crud.first_course(session))
        except crud.InvalidName as error:
            print(f"league: error: {error}", file=sys.stderr)
            return 1
        print(token)
    print(f"created {args.role} {user.name!r} (id {user.id}); the token above is shown once", file=sys.stderr)
    return 0


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

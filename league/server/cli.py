"""The server's commands of the `league` CLI: serve, worker, init, migrate, backup, restore, config, courses,
users.

league/cli.py calls `add_commands(subparsers)`; each command is run as `args.run(args)` and
returns the exit status. `python -m league.server ...` runs the same commands.
"""
from __future__ import annotations

import argparse
import logging
import signal
import sys
from datetime import datetime, timezone
from collections.abc import Callable
from pathlib import Path

from sqlalchemy import Engine
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, sessionmaker

from league.server.core.config import (
    Settings, database_origin, database_setting, describe_settings, load_settings, setting_sources,
    settings_markdown, unknown_variables,
)
from league.exit_codes import EXIT_ERROR, EXIT_OUTDATED
from league.server.db.models import INSTRUCTOR, STUDENT

log = logging.getLogger("league.server")


def add_commands(subparsers) -> None:
    where = argparse.ArgumentParser(add_help=False)
    where.add_argument("--data-dir", type=Path, metavar="DIR",
                       help="the server's data directory, its SQLite database included (default LEAGUE_DATA_DIR, "
                            "else agents_submissions in the current directory)")

    serve = subparsers.add_parser("serve", parents=[where], help="run the league server: the API and a worker",
                                  description="Run the API (OpenAPI docs at /docs) and, unless --no-worker, a "
                                              "`league worker` as its child process (stopped with it). Creates the "
                                              "database, or migrates it to this version's schema, first. Settings "
                                              "come from LEAGUE_* variables and .env (`league config`).")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    serve.add_argument("--no-worker", action="store_true", help="API only: jobs are run by `league worker`s")
    serve.add_argument("--threads", type=int, help="jobs its worker runs at once")
    serve.set_defaults(run=run_serve)

    worker = subparsers.add_parser("worker", parents=[where],
                                   help="run a worker (more of them: on this or other machines)",
                                   description="Run queued jobs until interrupted (Ctrl-C: once the running "
                                               "ones finish; SIGTERM: at once, handing them back). The database "
                                               "is the queue: point LEAGUE_DATABASE_URL at the league's "
                                               "PostgreSQL to work for a server on another machine.")
    worker.add_argument("--threads", type=int, help="jobs run at once (default LEAGUE_WORKER_THREADS)")
    worker.add_argument("--cpus", help="run on these CPUs only, e.g. 1 or 0-3,6 (default LEAGUE_WORKER_CPUS: all); "
                                       "the sandboxes it starts inherit them. Not needed to share a machine: "
                                       "the workers of one machine split its CPUs by themselves "
                                       "(LEAGUE_CPU_SLOTS_DIR)")
    worker.add_argument("--check", action="store_true",
                        help="exit 0 if the worker using this data directory reached the database recently, "
                             "else 1 with the reason (a container's health check; runs no worker)")
    worker.set_defaults(run=run_worker)

    init = subparsers.add_parser("init", parents=[where], help="create a new league's database",
                                 description="Create the database (an SQLite file in the data directory, or the "
                                             "schema in an empty LEAGUE_DATABASE_URL) and the data directory. "
                                             "Other commands never create a database: run from the wrong "
                                             "directory, they say where they looked.")
    init.add_argument("--instructor", metavar="NAME", help="also add this instructor and print their API token")
    init.set_defaults(run=run_init)

    migrate_ = subparsers.add_parser(
        "migrate", parents=[where], help="upgrade the database to this version's schema (or to a revision)",
        description="Run the migrations this version of microracer-league brings (`league serve` runs them too), "
                    "or with --to, upgrade or downgrade to that schema revision (a rollback: see the server README). "
                    "Back up first: league backup FILE. Refuses while processes of another version (API, workers) "
                    "are registered in the database: stop them first.")
    migrate_.add_argument("--to", metavar="REVISION", help="the schema revision to upgrade or downgrade to "
                                                           "(default: this version's, the newest)")
    migrate_.add_argument("--force", action="store_true",
                          help="forget the registered processes of another version that stopped beating (they "
                               "died); live ones still refuse")
    migrate_.set_defaults(run=run_migrate)

    backup = subparsers.add_parser("backup", parents=[where], help="write a snapshot of the league to a file",
                                   description="Write the league's whole state (its database: accounts, model "
                                               "files, results, replays) to FILE, an SQLite file readable by you "
                                               "only, while the server runs.")
    backup.add_argument("file", type=Path, metavar="FILE", help="where to write it (replaced if it exists); a "
                                                                 "directory: a new file league-DATE-TIME.db in it")
    backup.add_argument("--keep", type=int, metavar="N", help="with a directory: then delete all but its N newest "
                                                              "backups (a nightly cron job's rotation)")
    backup.set_defaults(run=run_backup)

    restore = subparsers.add_parser("restore", parents=[where], help="restore a backup into a new database",
                                    description="Restore a `league backup` FILE into a fresh data directory or an "
                                                "empty database, SQLite or PostgreSQL whatever the backup was taken "
                                                "from, migrated to this version's schema. Jobs queued or running at "
                                                "the backup run again once a worker starts.")
    restore.add_argument("file", type=Path, metavar="FILE", help="a file written by `league backup`")
    restore.add_argument("--replace", action="store_true",
                         help="overwrite a database that holds a league (every table of it is dropped); stop its "
                              "server and workers first")
    restore.set_defaults(run=run_restore)

    config = subparsers.add_parser("config", parents=[where], help="print the settings in effect",
                                   description="Print every setting as a line of .env, with where its value comes "
                                               "from (default, environment, .env, command line); passwords masked.")
    config.add_argument("--markdown", action="store_true", help="print the table of every setting (docs/SETTINGS.md)")
    config.set_defaults(run=run_config)

    courses = subparsers.add_parser("courses", help="manage the courses of the server",
                                    description="Several courses on one server: each has its own instructors, "
                                                "students, assignments, boards and results (the baselines are "
                                                "evaluated in each). An instructor manages their course only.")
    course_commands = courses.add_subparsers(dest="courses_command", required=True, metavar="{add,list}")
    course_add = course_commands.add_parser(
        "add", parents=[where], help="create a course (its default assignment, its baselines' evaluations)",
        description="Create a course with its default assignment at the server's default evaluation settings "
                    "and board visibility; the baselines are evaluated on it once a worker runs. Give it "
                    "instructors with --instructor, or later with `league users add NAME --course COURSE "
                    "--role instructor`.")
    course_add.add_argument("name", help="the course's name, unique on the server")
    course_add.add_argument("--instructor", metavar="LOGIN", help="also add this instructor and print their token")
    course_add.set_defaults(run=run_courses_add)
    course_list = course_commands.add_parser("list", parents=[where], help="list the courses")
    course_list.set_defaults(run=run_courses_list)
    in_course = argparse.ArgumentParser(add_help=False)
    in_course.add_argument("--course", metavar="NAME",
                           help="the course (`league courses list`); default: the first one")

    users = subparsers.add_parser("users", help="manage accounts")
    commands = users.add_subparsers(dest="users_command", required=True, metavar="{add,import,list,revoke,delete}")
    add = commands.add_parser("add", parents=[where, in_course], help="add an account and print its API token")
    add.add_argument("name")
    add.add_argument("--role", choices=[INSTRUCTOR, STUDENT], default=STUDENT, help="default: student")
    add.add_argument("--email", help="the student's email address (optional)")
    add.add_argument("--student-id", help="the school's id of the student, unique in the course (optional)")
    add.set_defaults(run=run_users_add)
    roster = commands.add_parser(
        "import", parents=[where, in_course],
        help="create the students of a roster (CSV) and print their tokens as CSV",
        description="Create the students of a roster as spreadsheets export it: comma-, semicolon- or "
                    "tab-separated, with a header naming the columns (name, or first name and last name; email; "
                    "student id; in common spellings) or one name a line. Students enrolled already are skipped "
                    "(matched by student id or email, else by name); each bad line is reported with its number "
                    "and the others are created. Writes name,email,student_id,token of the new students to "
                    "standard output (tokens are shown once: redirect it to a file); exits 1 if a line had an error.")
    roster.add_argument("file", help="the roster, e.g. roster.csv (UTF-8, as Excel's 'CSV UTF-8' saves it)")
    roster.set_defaults(run=run_users_import)
    listing = commands.add_parser("list", parents=[where], help="list the accounts")
    listing.set_defaults(run=run_users_list)
    revoke = commands.add_parser("revoke", parents=[where], help="revoke an account (its token stops working)")
    revoke.add_argument("name")
    revoke.set_defaults(run=run_users_revoke)
    delete = commands.add_parser(
        "delete", parents=[where], help="delete a student and their data for good",
        description="Delete a student: their account, token, submissions, model files and evaluations are erased "
                    "from the database (rows deleted, not hidden); races and championship standings other students "
                    "took part in keep their results, with the student's cars shown as 'deleted student'. The audit "
                    "log records the deletion by user id. Backups taken before still hold the student's data "
                    "(see the server README).")
    delete.add_argument("name")
    delete.add_argument("--yes", action="store_true", help="do not ask for confirmation (scripts)")
    delete.set_defaults(run=run_users_delete)


def _logged_setup(args: argparse.Namespace) -> tuple[Settings, dict[str, str]]:
    """serve's and worker's settings, then their logging as the settings say (league/server/core/logs.py);
    the settings' warnings are logged in that format."""
    from league.server.core.logs import configure

    warnings: list[str] = []
    settings, sources = _setup(args, warnings.append)
    configure(settings)
    for warning in warnings:
        log.warning(warning)
    return settings, sources


def _say(text: str) -> None:
    """What an admin command tells its user (stderr: stdout is for what it prints, such as a token)."""
    print(f"league: {text}", file=sys.stderr)


def _warn(text: str) -> None:
    _say(f"warning: {text}")


def _setup(args: argparse.Namespace, warn: Callable[[str], None] = _warn) -> tuple[Settings, dict[str, str]]:
    """The settings (command-line options over LEAGUE_* variables over .env) and where each came from;
    warns of LEAGUE_* variables that are no setting."""
    overrides = {"data_dir": getattr(args, "data_dir", None)}
    settings = load_settings(**overrides)
    for warning in unknown_variables():
        warn(warning)
    return settings, setting_sources(overrides)


def _open(settings: Settings, sources: dict[str, str], say: Callable[[str], None] = _say, *,
          create: bool = False) -> tuple[Engine, str | None]:
    """The league's database, named on stderr; created only if `create` (serve, init), else it must exist."""
    from league.server.db.session import open_engine, shown_url

    url = settings.resolved_database_url
    say(f"database {shown_url(url)} ({database_origin(settings, sources)})")
    missing = (f"no league database at {make_url(url).database}: run this command where the server runs, or point "
               f"it at the server's data directory with --data-dir DIR or LEAGUE_DATA_DIR=DIR (LEAGUE_DATABASE_URL "
               f"for PostgreSQL); `league init` creates a new league there")
    return open_engine(url, setting=database_setting(settings, sources), missing=missing, create=create)


def _sessions(args: argparse.Namespace) -> sessionmaker[Session]:
    """Sessions on the league's existing database, at this version's schema (admin commands)."""
    from league.server.bootstrap import ensure_course
    from league.server.db.session import check_schema, make_sessionmaker

    settings, sources = _setup(args)
    engine, revision = _open(settings, sources)
    check_schema(revision)
    sessions = make_sessionmaker(engine)
    ensure_course(sessions, settings)
    return sessions


def run_serve(args: argparse.Namespace) -> int:
    import uvicorn

    from league.server.api.connections import connection_limits, uvicorn_protocols
    from league.server.app import create_app
    from league.server.core.logs import settings_log_config
    from league.server.db.session import migrate
    from league.server.services import open_services
    from league.server.supervise import ChildWorker

    settings, sources = _logged_setup(args)
    protocols = uvicorn_protocols(connection_limits(settings))
    engine, _ = _open(settings, sources, log.info, create=True)
    before, after = migrate(engine, guard=process_guard(settings, force=False))
    if before != after:
        log.info("database migrated from revision %s to %s", before, after)
    services = open_services(settings, engine)
    app = create_app(settings, services)
    worker = None if args.no_worker else ChildWorker(args.threads, args.data_dir, settings.log_file)
    app.state.supervisor = worker  # its restarts at /metrics
    if worker is not None:
        worker.start()
    # uvicorn raises the SIGTERM or SIGINT it stopped on again once it is done: end here, not die there
    signal.signal(signal.SIGTERM, _exit_on_signal)
    try:
        uvicorn.run(app, host=args.host, port=args.port, log_level=settings.log_level,
                    log_config=settings_log_config(settings), access_log=False, **protocols)
    except KeyboardInterrupt:
        pass
    finally:
        if worker is not None:
            worker.stop()
    return 0


def _exit_on_signal(signum, frame) -> None:
    raise SystemExit(0)


def run_worker(args: argparse.Namespace) -> int:
    from league.server.db.session import check_schema
    from league.server.jobs.runner import lower_session_priority
    from league.server.jobs.worker import Worker, pin_to_cpus, worker_context

    settings, sources = _logged_setup(args)
    if args.check:
        return check_worker(settings)
    cpus = args.cpus if args.cpus is not None else settings.worker_cpus
    if cpus:
        try:
            log.info("worker: running on CPUs %s", ",".join(map(str, sorted(pin_to_cpus(cpus)))))
        except ValueError as error:
            print(f"league worker: --cpus {cpus!r}: {error}", file=sys.stderr)
            return EXIT_ERROR
    engine, revision = _open(settings, sources, lambda text: log.info("worker: %s", text))
    check_schema(revision)  # workers never migrate: `league serve` or `league migrate` does
    lower_session_priority(settings.job_nice)
    context = worker_context(settings, engine)
    worker = Worker(context, threads=args.threads or settings.worker_threads)
    worker.run_forever()
    return EXIT_OUTDATED if worker.outdated else 0


def check_worker(settings: Settings) -> int:
    from league.server.jobs.alive import alive_file, stale_reason

    reason = stale_reason(alive_file(settings.data_dir), settings.reaper_interval_s)
    if reason:
        print(f"league worker --check: unhealthy: {reason}", file=sys.stderr)
        return 1
    return 0


def run_init(args: argparse.Namespace) -> int:
    from league.server.bootstrap import ensure_course
    from league.server.db.session import make_sessionmaker, migrate
    from league.server.storage import BlobStore

    settings, sources = _setup(args)
    engine, _ = _open(settings, sources, create=True)
    before, revision = migrate(engine, new_only=True)
    _say(f"created a new league (schema revision {revision})" if before is None else
         f"this database already holds a league (schema revision {revision}): nothing to create")
    BlobStore(settings.data_dir).ensure()
    sessions = make_sessionmaker(engine)
    ensure_course(sessions, settings)
    return _add_user(sessions, args.instructor, INSTRUCTOR) if args.instructor else 0


def process_guard(settings: Settings, force: bool) -> Callable:
    """What `migrate` runs before changing the schema: refuse while processes of another version run."""
    from league.server.jobs.registry import refuse_other_versions

    return lambda connection: refuse_other_versions(connection, settings.worker_silent_after_s, force)


def run_migrate(args: argparse.Namespace) -> int:
    from league.server.db.session import DatabaseError, known_revision, migrate, schema_problem, schema_state

    settings, sources = _setup(args)
    engine, revision = _open(settings, sources)
    if schema_state(revision) == "empty":
        raise DatabaseError(schema_problem(revision))
    before, after = migrate(engine, to=known_revision(args.to) if args.to else "head",
                            guard=process_guard(settings, args.force))
    _say(f"migrated from schema revision {before} to {after}" if before != after else
         f"already at schema revision {after}: nothing to do")
    return 0


def run_backup(args: argparse.Namespace) -> int:
    from league.server.backup import backup

    if args.keep is not None and (args.keep < 1 or not args.file.is_dir()):
        raise ValueError("--keep takes a number of backups, at least 1, and a directory as FILE")
    settings, sources = _setup(args)
    engine, revision = _open(settings, sources)
    from league.server.db.session import head_revision

    target = args.file / f"league-{datetime.now(timezone.utc):%Y%m%d-%H%M%S}.db" if args.file.is_dir() else args.file
    report = backup(engine, revision, target)
    if revision == head_revision():  # (a backup before an upgrade: the older schema's log is not written to)
        _record_admin(engine, "backup", file=str(Path(target).resolve()), revision=report.revision,
                      rows=report.counts, size=report.size)
    _say(f"backed up to {target}: {report.summary()}")
    if args.keep is not None:
        for old in sorted(args.file.glob("league-*.db"), reverse=True)[args.keep:]:  # the names sort by time
            old.unlink()
            _say(f"deleted the older backup {old}")
    return 0


def run_restore(args: argparse.Namespace) -> int:
    from league.server.backup import restore
    from league.server.db.session import head_revision, shown_url

    settings, sources = _setup(args)
    url = settings.resolved_database_url
    if make_url(url).get_backend_name() == "sqlite":
        _say(f"database {shown_url(url)} ({database_origin(settings, sources)})")
    else:  # it must exist and answer; an SQLite file is written whole
        _open(settings, sources, create=True)[0].dispose()
    report = restore(args.file, url, replace=args.replace)
    from league.server.db.session import make_engine

    restored = make_engine(url)
    try:  # in the restored database's log, after the backup's own events
        _record_admin(restored, "restore", file=str(Path(args.file).resolve()), revision=report.revision,
                      rows=report.counts, replaced=bool(args.replace), migrated_to=head_revision())
    finally:
        restored.dispose()
    _say(f"restored {args.file}: {report.summary()}, migrated to {head_revision()}. Jobs queued or running at "
         f"the backup run as soon as a worker starts")
    return 0


def _record_admin(engine, command: str, **details) -> None:
    """An admin command's event in the audit log (backups and restores: they can change every grade)."""
    from league.server.course import audit
    from league.server.db.session import make_sessionmaker

    action = {"backup": audit.BACKUP, "restore": audit.RESTORE}[command]
    with make_sessionmaker(engine).begin() as session:
        audit.record(session, actor=None, action=action, target_kind="league", **details)


def run_config(args: argparse.Namespace) -> int:
    if args.markdown:
        print(settings_markdown(), end="")
        return 0
    settings, sources = _setup(args)
    print(describe_settings(settings, sources))
    return 0


def _add_user(sessions: sessionmaker[Session], name: str, role: str, course_name: str | None = None,
              **identity: str | None) -> int:
    from league.server.course import audit
    from league.server.course.courses import CourseRefused, existing_course
    from league.server.db import crud

    with sessions.begin() as session:
        try:
            user, token = crud.create_user(session, name=name, role=role,
                                           course=existing_course(session, course_name), **identity)
        except (crud.InvalidAccount, CourseRefused) as error:
            print(f"league: error: {error}", file=sys.stderr)
            return 1
        audit.record(session, actor=None, action=audit.CREATE_USER, target_kind="user", target_id=user.id,
                     course_id=user.course_id)
        print(token, flush=True)  # before the line below on stderr, which names it "above"
        created = f"created {role} {user.name!r} (id {user.id}) in the course {user.course.name!r}"
    _say(f"{created}; the token above is shown once")
    return 0


def run_users_add(args: argparse.Namespace) -> int:
    return _add_user(_sessions(args), args.name, args.role, args.course, email=args.email,
                     student_id=args.student_id)


def run_courses_add(args: argparse.Namespace) -> int:
    from league.server.course import audit
    from league.server.course.courses import CourseRefused, add_course
    from league.server.jobs.queue import JobQueue

    sessions = _sessions(args)
    with sessions.begin() as session:
        try:
            course, jobs = add_course(session, name=args.name, settings=load_settings(data_dir=args.data_dir))
        except CourseRefused as error:
            print(f"league: error: {error}", file=sys.stderr)
            return 1
        audit.record(session, actor=None, action=audit.CREATE_COURSE, target_kind="course", target_id=course.id,
                     course_id=course.id, name=course.name)
        name, course_id, job_ids = course.name, course.id, [job.id for job in jobs]
    queue = JobQueue(sessions.kw["bind"])  # wakes the workers (PostgreSQL); else their next poll finds the jobs
    for job_id in job_ids:
        queue.enqueue(job_id)
    _say(f"created the course {name!r} (id {course_id}); {_count(len(job_ids), 'baseline evaluation')} queued for "
         f"its default assignment")
    return _add_user(sessions, args.instructor, INSTRUCTOR, name) if args.instructor else 0


def run_courses_list(args: argparse.Namespace) -> int:
    from league.server.course.courses import course_counts

    with _sessions(args)() as session:
        for course, instructors, students in course_counts(session):
            print(f"{course.id:>5}  {course.name:<30} {_count(instructors, 'instructor'):<15} "
                  f"{_count(students, 'student'):<14} boards: {course.board_visibility}")
    return 0


def run_users_import(args: argparse.Namespace) -> int:
    from league.server.course import audit
    from league.server.course.courses import CourseRefused, existing_course
    from league.server.course.roster import MAX_ROSTER_BYTES, RosterError, import_roster, read_roster
    from league.spreadsheet import csv_text

    try:
        with open(args.file, "rb") as file:
            roster = read_roster(file.read(MAX_ROSTER_BYTES + 1))
    except (OSError, RosterError) as error:
        print(f"league: error: {args.file}: {error}", file=sys.stderr)
        return 1
    with _sessions(args).begin() as session:
        try:
            course = existing_course(session, args.course)
        except CourseRefused as error:
            print(f"league: error: {error}", file=sys.stderr)
            return 1
        report = import_roster(session, course=course, created_by=None, roster=roster)
        audit.record(session, actor=None, action=audit.IMPORT_ROSTER, target_kind="roster", course_id=course.id,
                     created=[user.id for user, _ in report.created], skipped=len(report.skipped),
                     errors=len(report.errors))
        tokens = csv_text(["name", "email", "student_id", "token"],
                          ([user.name, user.email, user.student_id, token] for user, token in report.created))
    sys.stdout.write(tokens)  # once committed
    sys.stdout.flush()  # before the lines below on stderr, which say "the tokens above"
    for problem in report.skipped:
        print(f"line {problem.line}: skipped{' ' + problem.name if problem.name else ''}: {problem.reason}",
              file=sys.stderr)
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

    with _sessions(args)() as session:
        for user in session.scalars(select(User).order_by(User.id)):
            state = "active" if user.active else "revoked"
            print(f"{user.id:>5}  {user.name:<30} {user.role:<10} {state:<8} {user.course.name if user.course else ''}")
    return 0


def run_users_revoke(args: argparse.Namespace) -> int:
    from league.server.course import audit
    from league.server.db import crud

    with _sessions(args).begin() as session:
        user = crud.user_by_name(session, name=args.name)
        if user is None:
            print(f"league: error: no user {args.name!r}", file=sys.stderr)
            return 1
        crud.revoke_user(session, user=user)
        audit.record(session, actor=None, action=audit.REVOKE, target_kind="user", target_id=user.id,
                     course_id=user.course_id)
    _say(f"revoked {args.name!r}")
    return 0


def run_users_delete(args: argparse.Namespace) -> int:
    from league.server.course import audit
    from league.server.course.erasure import DeletionRefused, delete_student, write_out
    from league.server.db import crud
    from league.server.storage import BlobStore

    sessions = _sessions(args)
    if not args.yes and not _confirmed(f"delete the student {args.name!r} and all their data for good? "
                                       "type their name to confirm: ", args.name):
        print("league: error: not confirmed (type the name, or pass --yes); nothing deleted", file=sys.stderr)
        return 1
    with sessions.begin() as session:
        user = crud.user_by_name(session, name=args.name)
        if user is None:
            print(f"league: error: no user {args.name!r}", file=sys.stderr)
            return 1
        try:
            user_id, course_id, erased = user.id, user.course_id, delete_student(session, user=user)
        except DeletionRefused as refusal:
            print(f"league: error: {refusal}", file=sys.stderr)
            return 1
        audit.record(session, actor=None, action=audit.DELETE_USER, target_kind="user", target_id=user_id,
                     course_id=course_id, note="student and their data deleted", **erased.summary())
    if not write_out(sessions.kw["bind"]):
        _say("the database's write-ahead log was in use: SQLite empties it at a later checkpoint")
    store = BlobStore(load_settings(data_dir=args.data_dir).data_dir)
    for sha256 in erased.blobs:
        store.remove(sha256)
    counts = erased.summary()
    _say(f"deleted the student {args.name!r} (id {user_id}): {_count(counts['submissions'], 'submission')}, "
         f"{_count(counts['evaluations'], 'evaluation')}, {_count(counts['files'], 'model file')}, "
         f"{_count(counts['races_deleted'], 'friendly race')} erased; {_count(counts['races_kept'], 'race')} "
         f"others took part in kept, their cars shown as deleted")
    return 0


def _confirmed(prompt: str, expected: str) -> bool:
    if not sys.stdin.isatty():
        return False
    try:
        return input(prompt).strip() == expected
    except EOFError:
        return False


def main(argv: list[str] | None = None) -> int:
    from league.command import add_version, run

    parser = argparse.ArgumentParser(prog="python -m league.server", description="MicroRacer League server")
    add_version(parser)
    add_commands(parser.add_subparsers(dest="command", required=True))
    return run(parser, argv)

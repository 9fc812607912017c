"""Benchmark of a course's due time: 200 finals tested on the private tracks, to a published board.

    python benchmarks/bench_course.py [--backend sqlite|postgres] [--students 200] [--episodes 20]
    python benchmarks/bench_course.py --backlog [--backend sqlite|postgres] [--students 200] [--window 120]

A course of --students students (a roster imported through the API) with three assignments (a time
trial without obstacles, then obstacles, then chicanes; --episodes episodes each, public and
private). Each student uploads an agent to the first (bench_rush.py's working files: ONNX and
TorchScript, compact and lidar, dynamic and fixed batch), evaluated on its public tracks by two
`league worker`s beside `league serve --no-worker`, all with their default settings (a reaper pass
every 10 s). Once the queue is empty, the instructor moves the first assignment's due time to 3 s
from now; it publishes itself (auto_publish) once every final is tested.

Printed, beside bench_rush.py's figures: the time from the due time to the published private board
(the server's own `due_at` and `published_at`; target <= 120 s), and how long the private tests
took from the first to the last. Checked, exit status 1 if one fails: every student on the private
board, each final tested on --episodes private episodes; no job failed; the other two
assignments unpublished.

--backlog: the due time with the queue behind. The workers are stopped once the baselines are
evaluated; each student uploads an agent in the last --window seconds before the due time (evenly
spread); the workers start again only once the due time has passed, so at the due time every upload
is still to be validated and evaluated. Printed: the time from the due time to the published private
board (auto_publish) with every student who uploaded graded, and from the last evaluation done to
the publication (target <= 300 s); checked, exit status 1 if one fails: no student who uploaded in
time without a final (their grade "no final"), every one of them graded and on the private board
(read just after the publication: it waited for them), no job failed.
"""
from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

from _league import (
    Deadline, League, checks_line, course_files, course_league, enrol, machine, run_script, student_names,
    wait_queue_empty,
)

TARGET_S = 120.0
DUE_IN_S = 3.0
BACKLOG_TARGET_S = 300.0  # the last evaluation done -> the private board published
RUBRIC = {"kind": "points", "max_points": 10, "completed": {"kind": "linear", "points": 10}}
ASSIGNMENTS = (("time trial", {"obstacles": False, "chicanes": False}, 0),
               ("obstacles", {"obstacles": True, "chicanes": False}, 7),
               ("chicanes", {"obstacles": True, "chicanes": True}, 14))  # name, env options, due in days


def create_assignments(instructor, episodes: int) -> list[dict]:
    now = datetime.now(timezone.utc)
    created = []
    for name, options, days in ASSIGNMENTS:
        body = {"name": name, "episodes": episodes, "env_options": options, "auto_publish": True,
                "due_at": (now + timedelta(days=days + 1)).isoformat()}
        response = instructor.post("/api/assignments", json=body)
        response.raise_for_status()
        created.append(response.json())
    return created


def upload_all(league: League, tokens: list[str], files: list[Path], assignment: str) -> None:
    def send(k: int) -> None:
        with league.client(tokens[k]) as student:
            path = files[k % len(files)]
            response = student.post("/api/submissions", data={"assignment": assignment},
                                    files={"file": (path.name, path.read_bytes())})
            response.raise_for_status()

    with ThreadPoolExecutor(8) as pool:
        list(pool.map(send, range(len(tokens))))


def wait_published(instructor, assignment_id: int, timeout: float) -> dict:
    deadline = Deadline(timeout, "the private board's publication")
    while True:
        assignment = instructor.get(f"/api/assignments/{assignment_id}").json()
        if assignment["published_at"]:
            return assignment
        deadline.check(assignment)
        time.sleep(0.2)


def private_tests(instructor, due: datetime) -> list[dict]:
    """The evaluations that started after the due time: the finals' private tests."""
    jobs = instructor.get("/api/jobs", params={"limit": 500}).json()
    return [job for job in jobs if job["kind"] == "evaluate" and job["started_at"]
            and datetime.fromisoformat(job["started_at"].replace("Z", "+00:00")) >= due]


@dataclass
class CourseFigures:
    """What a course's due time measured, and what its checks found (`failures`: none when all passed)."""

    students: int
    episodes: int  # of each private test
    public_s: float  # the uploads validated and evaluated on the public tracks
    publish_s: float  # the due time -> the private board published (the server's own times)
    private_span_s: float  # the first private test's start -> the last one's end
    finals: int  # rows of the private board
    failures: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.failures


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog="\n".join(__doc__.splitlines()[4:]),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite")
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--episodes", type=int, default=20, help="episodes of each assignment's evaluations")
    parser.add_argument("--distinct", type=int, default=8, help="different agent files (bench_rush.py's kinds)")
    parser.add_argument("--backlog", action="store_true",
                        help="the backlog run: uploads in the last --window s, the workers stopped until the due time")
    parser.add_argument("--window", type=float, default=120.0, help="--backlog: the seconds before the due time "
                                                                    "in which the students upload")
    return parser.parse_args(argv)


def measure(args: argparse.Namespace) -> CourseFigures:
    """The course of `args` (parse()'s options) on a league of its own, stopped and removed afterwards."""
    with course_league(args.backend, "league-course-") as (league, folder, _):
        files = course_files(folder / "files", args.distinct)
        return course(league, args, files)


def report(figures: CourseFigures) -> None:
    f = figures
    print(f"  {f.students} uploads validated and evaluated on the public tracks in {f.public_s:.1f} s")
    print(f"  due time -> private board published ({f.finals} finals, {f.episodes} private episodes each): "
          f"{f.publish_s:.1f} s (target <= {TARGET_S:g} s: {'ok' if f.publish_s <= TARGET_S else 'OVER TARGET'}); "
          f"the private tests ran {f.private_span_s:.1f} s, first start to last finish")
    print(checks_line(f.failures, "every student's final on the private board, no job failed, the other "
                                  "assignments untouched"), flush=True)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.backlog:
        print(f"{machine()}; {args.backend}: backlog run, {args.students} students uploading in the last "
              f"{args.window:g} s before the due time, {args.episodes}-episode evaluations, 2 workers stopped until "
              f"the due time", flush=True)
        backlog_figures = measure_backlog(args)
        report_backlog(backlog_figures)
        return 0 if backlog_figures.passed else 1
    print(f"{machine()}; {args.backend}: {args.students} students, 3 assignments, {args.episodes}-episode "
          f"evaluations, 2 workers", flush=True)
    figures = measure(args)
    report(figures)
    return 0 if figures.passed else 1


def course(league: League, args: argparse.Namespace, files: list[Path]) -> CourseFigures:
    with league.client() as instructor:
        tokens = enrol(instructor, student_names(args.students))
        assignments = create_assignments(instructor, args.episodes)
        first = assignments[0]
        wait_queue_empty(league, 600)  # the baselines on the new assignments' tracks
        started = time.perf_counter()
        upload_all(league, tokens, files, first["name"])
        wait_queue_empty(league, 600 + 15 * args.students)  # a loaded 2-core machine: ~5 s a job
        public_s = time.perf_counter() - started
        due = datetime.now(timezone.utc) + timedelta(seconds=DUE_IN_S)
        instructor.patch(f"/api/assignments/{first['id']}", json={"due_at": due.isoformat()}).raise_for_status()
        published = wait_published(instructor, first["id"], timeout=600)
        tests = sorted(private_tests(instructor, due), key=lambda job: job["started_at"])
        board = instructor.get(f"/api/assignments/{first['id']}/board",
                               params={"board": "private", "size": 100, "page": 1}).json()
        rows = board["items"] + instructor.get(f"/api/assignments/{first['id']}/board", params={
            "board": "private", "size": 100, "page": 2}).json()["items"]
        others = [instructor.get(f"/api/assignments/{a['id']}").json() for a in assignments[1:]]
        failed = instructor.get("/api/jobs", params={"status": "failed", "limit": 10}).json()
    seconds = (datetime.fromisoformat(published["published_at"])
               - datetime.fromisoformat(published["due_at"])).total_seconds()
    span = (max(datetime.fromisoformat(job["finished_at"]) for job in tests)
            - datetime.fromisoformat(tests[0]["started_at"])).total_seconds() if tests else math.nan
    failures = []
    if board["total"] != args.students or any(row["stale"] or row["episodes"] != args.episodes for row in rows):
        failures.append(f"the private board has {board['total']} rows, not {args.students} of "
                        f"{args.episodes} episodes")
    if failed:
        failures.append(f"jobs failed: {[(job['id'], job['error']) for job in failed]}")
    if any(other["published_at"] for other in others):
        failures.append("another assignment was published")
    return CourseFigures(students=args.students, episodes=args.episodes, public_s=public_s, publish_s=seconds,
                         private_span_s=span, finals=board["total"], failures=failures)


# --------------------------------------------------------------------------- the backlog run


@dataclass
class BacklogFigures:
    """What a due time with the queue behind measured (`failures`: none when every check passed)."""

    students: int
    uploaded: int  # uploads accepted before the due time (one a student)
    episodes: int
    window_s: float
    publish_s: float  # the due time -> the private board published (the server's own times)
    jobs_s: float  # the workers started -> the last evaluation done
    after_last_s: float  # the last evaluation done -> the private board published (to the second)
    graded: int  # of the students who uploaded, those graded when it was published
    without_final: int  # of the students who uploaded, those whose grade is "no final": must be 0
    failures: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.failures


def measure_backlog(args: argparse.Namespace) -> BacklogFigures:
    """The backlog run of `args` (parse()'s options, --backlog) on a league of its own, stopped and
    removed afterwards."""
    with course_league(args.backend, "league-backlog-") as (league, folder, _):
        files = course_files(folder / "files", args.distinct)
        return backlog(league, args, files)


def report_backlog(figures: BacklogFigures) -> None:
    f = figures
    print(f"  {f.uploaded} of {f.students} students uploaded in the last {f.window_s:g} s before the due time, "
          f"the workers stopped until it")
    print(f"  due time -> private board published, every student who uploaded graded ({f.graded}, "
          f"{f.episodes} private episodes each): {f.publish_s:.1f} s; the jobs ran {f.jobs_s:.1f} s from the "
          f"workers' start; last evaluation done -> published: {f.after_last_s:.1f} s (target <= "
          f"{BACKLOG_TARGET_S:g} s: {'ok' if f.after_last_s <= BACKLOG_TARGET_S else 'OVER TARGET'})")
    print(f"  students who uploaded in time without a final: {f.without_final} (must be 0)")
    print(checks_line(f.failures, "no student who uploaded in time without a final, every one graded and on the "
                                  "private board at its publication, no job failed"), flush=True)


def upload_before(league: League, tokens: list[str], files: list[Path], assignment: str,
                  start: float, end: float) -> list[int]:
    """Student k uploads at start + k (end - start) / n (time.time()); the indices whose upload was accepted."""
    def send(k: int) -> int | None:
        time.sleep(max(0.0, start + k * (end - start) / len(tokens) - time.time()))
        with league.client(tokens[k]) as student:
            path = files[k % len(files)]
            response = student.post("/api/submissions", data={"assignment": assignment},
                                    files={"file": (path.name, path.read_bytes())})
        return k if response.status_code == 201 else None

    with ThreadPoolExecutor(8) as pool:
        return [k for k in pool.map(send, range(len(tokens))) if k is not None]


def backlog(league: League, args: argparse.Namespace, files: list[Path]) -> BacklogFigures:
    names = student_names(args.students)
    with league.client() as instructor:
        tokens = enrol(instructor, names)
        body = {"name": "deadline rush", "episodes": args.episodes, "auto_publish": True,
                "due_at": (datetime.now(timezone.utc) + timedelta(days=1)).isoformat()}
        created = instructor.post("/api/assignments", json=body)
        created.raise_for_status()
        assignment = created.json()
        instructor.put(f"/api/assignments/{assignment['id']}/rubric", json=RUBRIC).raise_for_status()
        wait_queue_empty(league, 600)  # the baselines on its tracks
        league.stop_workers()
        margin = min(5.0, args.window / 4)  # the last upload is answered before the due time
        due = datetime.now(timezone.utc) + timedelta(seconds=args.window)
        instructor.patch(f"/api/assignments/{assignment['id']}", json={"due_at": due.isoformat()}).raise_for_status()
        start = time.time()
        uploaded = upload_before(league, tokens, files, assignment["name"], start, due.timestamp() - margin)
        time.sleep(max(0.0, due.timestamp() + 1 - time.time()))
        workers_at = datetime.now(timezone.utc)
        for _ in range(2):
            league.start_worker()
        published = wait_published(instructor, assignment["id"], timeout=600 + 20 * args.students)
        rows = instructor.get(f"/api/assignments/{assignment['id']}/grades").json()["rows"]
        board = instructor.get(f"/api/assignments/{assignment['id']}/board",
                               params={"board": "private", "size": 1, "page": 1}).json()
        done = instructor.get("/api/jobs", params={"status": "done", "limit": 1000}).json()
        failed = instructor.get("/api/jobs", params={"status": "failed", "limit": 10}).json()
    published_at = datetime.fromisoformat(published["published_at"])
    last_done = max((datetime.fromisoformat(job["finished_at"]) for job in done
                     if job["kind"] == "evaluate" and job["finished_at"]), default=published_at)
    uploaders = {names[k] for k in uploaded}
    status = {row["name"]: row["status"] for row in rows if row["role"] == "student"}
    without_final = sorted(name for name in uploaders if status.get(name) == "no final")
    ungraded = sorted(name for name in uploaders if status.get(name) != "graded")
    failures = []
    if len(uploaded) != args.students:
        failures.append(f"{args.students - len(uploaded)} uploads were refused before the due time")
    if without_final:
        failures.append(f"{len(without_final)} students who uploaded in time have no final: {without_final[:5]}")
    if ungraded:
        failures.append(f"{len(ungraded)} students who uploaded in time were not graded at the publication: "
                        f"{[(name, status.get(name)) for name in ungraded[:5]]}")
    if board["total"] != len(uploaded):
        failures.append(f"the private board has {board['total']} rows, not {len(uploaded)}")
    if failed:
        failures.append(f"jobs failed: {[(job['id'], job['error']) for job in failed]}")
    return BacklogFigures(
        students=args.students, uploaded=len(uploaded), episodes=args.episodes, window_s=args.window,
        publish_s=(published_at - datetime.fromisoformat(published["due_at"])).total_seconds(),
        jobs_s=(last_done - workers_at).total_seconds(),
        after_last_s=max(0.0, (published_at - last_done).total_seconds()),  # published_at is to the second
        graded=len(uploaders) - len(ungraded), without_final=len(without_final), failures=failures)


if __name__ == "__main__":
    run_script(main)

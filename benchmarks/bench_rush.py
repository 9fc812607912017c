"""Benchmark of a deadline rush: a whole course uploads its agents at once, then races a round.

    python benchmarks/bench_rush.py [--backend sqlite|postgres] [--students 200] [--uploads 600]
                                    [--window-s 300] [--episodes 100] [--faults]

A course of --students students (a roster imported through the API) uploads --uploads agents at
even intervals over --window-s seconds, student after student: ONNX and TorchScript, compact (5)
and lidar (20) observations, dynamic and fixed batch (--distinct different files), and 10 %
broken ones (wrong input size, wrong output size, NaN actions, a pickle, an empty file), never a
student's first upload. Two `league worker`s run beside `league serve --no-worker`; meanwhile
--status-clients students poll their latest submission's status every 2 s (plain GETs, as
`league submit --wait` does) and --board-clients clients the leaderboard every 5 s. Once the
queue is empty the clients poll on for --idle-s (the idle figures), then the instructor runs a
championship round of every student's active agent in heats of 10.

Printed: the time from the last upload to an empty queue (target <= 60 s); p50/p99 of the status
and leaderboard answers during the rush (target p99 <= 50 ms), idle and during the round; the
round's wall time, and where it went (the heats' run times; the queue's waits: the first heat's
claim, the workers' idle time between heats; the last heat's tail after the other worker's).
Checked, exit status 1 if one fails: every upload accounted for (good ones ready and evaluated,
broken ones refused with a reason), one submission per accepted upload; no job left queued or
running, failed, or done twice (from the database); every evaluation equal, figure for figure, to
`metrics_run` of the same file with the course's seed and episodes, run here; the round done
with every student in exactly one heat.

--faults: halfway through the window, as soon as a worker runs a job (30 s at most), that worker
is killed (SIGKILL) and the API restarted (SIGTERM, started again), then a worker is started
again; the killed job must run again elsewhere and count once. Requests refused while the API is
down are counted apart; uploads are retried as a student would (by name: never twice).
Everything runs on this machine: servers on 127.0.0.1 in a temporary directory, bounded waits.
"""
from __future__ import annotations

import argparse
import heapq
import math
import multiprocessing
import random
import subprocess
import threading
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from _league import (
    Deadline, League, broken_files, checks_line, course_files, course_league, course_settings, enrol, machine,
    percentiles_ms, run_script, student_names, wait_queue_empty,
)
from bench_league import HeatWaits

QUEUE_TARGET_S = 60.0
P99_TARGET_MS = 50.0
HEAT_SIZE = 10
BROKEN_SHARE = 0.10
STATUS_PERIOD_S, BOARD_PERIOD_S = 2.0, 5.0
FIGURES = ("completed", "episodes_total", "mean_return", "mean_steps", "mean_speed")


# --------------------------------------------------------------------------- the files and who uploads what


@dataclass
class Upload:
    index: int
    student: int
    file: Path
    broken: bool
    code: int | None = None  # the HTTP status of the POST (201 accepted)
    submission_id: int | None = None
    detail: str = ""
    answered_at: float = 0.0

    @property
    def name(self) -> str:
        return f"upload-{self.index:04d}"


def plan(students: int, uploads: int, good: list[Path], broken: list[Path], seed: int) -> list[Upload]:
    """Upload i is student i mod `students`'s; the broken ones are drawn among the uploads that are
    not a student's first, so that every student has an agent for the round."""
    rng = random.Random(seed)
    spoiled = set(rng.sample(range(students, uploads), min(uploads - students, round(BROKEN_SHARE * uploads))))
    plan_, next_broken = [], 0
    for i in range(uploads):
        if i in spoiled:
            plan_.append(Upload(i, i % students, broken[next_broken % len(broken)], True))
            next_broken += 1
        else:
            plan_.append(Upload(i, i % students, good[i % len(good)], False))
    return plan_


# --------------------------------------------------------------------------- clients


def bearer(token: str | None) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"} if token else {}


class Pollers:
    """Clients each polling a GET every `period` seconds (from a random phase), a few clients per
    thread; each answer's latency is kept under the phase (rush, idle, round) it was sent in."""

    def __init__(self, url: str, seed: int):
        self.url, self.rng = url, random.Random(seed)
        self.phase = "warm-up"
        self.latencies: dict[tuple[str, str], list[float]] = defaultdict(list)
        self.errors: list[tuple[float, str, str]] = []  # (sent at, what, status or exception)
        self.lock, self.stop = threading.Lock(), threading.Event()
        self.threads: list[threading.Thread] = []

    def add(self, what: str, clients: list, period: float, per_thread: int = 5) -> None:
        """`clients`: functions returning (path, token) to GET now, or None (nothing to poll yet)."""
        for first in range(0, len(clients), per_thread):
            phases = [self.rng.uniform(0, period) for _ in clients[first:first + per_thread]]
            thread = threading.Thread(target=self._poll, args=(what, clients[first:first + per_thread], period, phases),
                                      daemon=True)
            self.threads.append(thread)
            thread.start()

    def _poll(self, what: str, clients: list, period: float, phases: list[float]) -> None:
        import httpx

        start = time.perf_counter()
        due = [(start + phase, k) for k, phase in enumerate(phases)]
        heapq.heapify(due)
        with httpx.Client(base_url=self.url, timeout=30) as http:
            while True:
                at, k = heapq.heappop(due)
                heapq.heappush(due, (at + period, k))
                if self.stop.wait(max(0.0, at - time.perf_counter())):
                    return
                target = clients[k]()
                if target is None:
                    continue
                phase, sent = self.phase, time.perf_counter()
                try:
                    status = http.get(target[0], headers=bearer(target[1])).status_code
                except httpx.HTTPError as error:
                    status = repr(error)
                elapsed = time.perf_counter() - sent
                with self.lock:
                    if status == 200:
                        self.latencies[what, phase].append(elapsed)
                    else:
                        self.errors.append((sent, what, str(status)))

    def close(self) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join()


class Uploader:
    """Sends the planned uploads open loop (upload i due at i * window / count) from a few threads,
    as the students' clients would: retried while the API cannot be reached, never sent twice."""

    def __init__(self, league: League, tokens: list[str], uploads: list[Upload], window_s: float):
        self.league, self.tokens, self.uploads, self.window_s = league, tokens, uploads, window_s
        self.latest: dict[int, int] = {}  # student -> their newest accepted submission
        self.lock = threading.Lock()

    def run(self, senders: int = 8) -> None:
        start = time.perf_counter()
        threads = [threading.Thread(target=self._send_share, args=(k, senders, start)) for k in range(senders)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()

    def _send_share(self, offset: int, senders: int, start: float) -> None:
        import httpx

        interval = self.window_s / max(1, len(self.uploads) - 1)
        with httpx.Client(base_url=self.league.url, timeout=60) as http:
            for upload in self.uploads[offset::senders]:
                delay = start + upload.index * interval - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                self._send(http, upload)

    def _send(self, http, upload: Upload) -> None:
        import httpx

        headers = bearer(self.tokens[upload.student])
        deadline = Deadline(180, f"{upload.name}: the API is unreachable")
        while True:
            try:
                with open(upload.file, "rb") as handle:
                    response = http.post("/api/submissions", files={"file": (upload.file.name, handle)},
                                         data={"name": upload.name}, headers=headers)
                break
            except (httpx.ConnectError, httpx.ConnectTimeout) as error:  # not sent: try again
                deadline.check(error)
            except httpx.HTTPError as error:  # sent, no answer: accepted or not, the student's list says
                found = self._find(http, upload, headers, deadline)
                if found is not None:
                    self._accepted(upload, 201, found)
                    return
                deadline.check(error)
            time.sleep(0.2)
        if response.status_code == 201:
            self._accepted(upload, 201, response.json()["id"])
        else:
            upload.code, upload.detail, upload.answered_at = response.status_code, response.text, time.perf_counter()

    def _find(self, http, upload: Upload, headers: dict, deadline: Deadline) -> int | None:
        import httpx

        while True:
            try:
                listing = http.get("/api/submissions", headers=headers)
                if listing.status_code == 200:
                    return next((s["id"] for s in listing.json() if s["name"] == upload.name), None)
            except httpx.HTTPError as error:
                deadline.check(error)
            time.sleep(0.2)

    def _accepted(self, upload: Upload, code: int, submission_id: int) -> None:
        upload.code, upload.submission_id, upload.answered_at = code, submission_id, time.perf_counter()
        with self.lock:
            self.latest[upload.student] = submission_id


# --------------------------------------------------------------------------- the rush


def inject_faults(league: League, at: float, events: dict[str, float]) -> None:
    """At `at` (perf_counter), kill (SIGKILL) a worker as soon as one runs a job (up to 30 s later,
    else the first), restart the API, then start a new worker."""
    time.sleep(max(0.0, at - time.perf_counter()))
    victim, job_id = busy_worker(league, timeout=30.0)
    league.workers.remove(victim)
    victim.kill()
    victim.wait()
    events[f"worker killed (running job {job_id})" if job_id else "worker killed (idle)"] = time.perf_counter()
    events["API down"] = time.perf_counter()
    league.restart_api()
    events["API up"] = time.perf_counter()
    league.start_worker(wait=True)
    events["worker started"] = time.perf_counter()


def busy_worker(league: League, timeout: float) -> tuple[subprocess.Popen, int | None]:
    """A worker process with a running job (attempt ids are host/pid/nonce), and that job's id; the
    first worker and None if none runs one within `timeout`."""
    by_pid = {worker.pid: worker for worker in league.workers}
    end = time.perf_counter() + timeout
    with league.client() as instructor:
        while time.perf_counter() < end:
            for job in instructor.get("/api/jobs", params={"status": "running"}).json():
                pid = int((job["worker_id"] or "//").split("/")[1] or 0)
                if pid in by_pid:
                    return by_pid[pid], job["id"]
            time.sleep(0.02)
    return league.workers[0], None


def run_round(league: League, seed: int, students: int) -> tuple[float, dict]:
    """The round's seconds from POST to done, and its summary with its races and `waits` (HeatWaits)."""
    from bench_league import heat_report, new_championship, timed_round

    with league.client() as instructor:
        championship_id = new_championship(instructor, "deadline cup", seed)
        seconds, summary = timed_round(instructor, championship_id, timeout=120 + 20 * students)
        summary["races"] = [instructor.get(f"/api/races/{race_id}").json() for race_id in summary["race_ids"]]
        _, summary["heats_s"], summary["waits"] = heat_report(instructor, summary)
    return seconds, summary


# --------------------------------------------------------------------------- checks


def local_figures(path: str, settings: dict) -> dict:
    """metrics_run of the file here, outside any sandbox (a process of a pool)."""
    from league.agents import load_agent
    from league.evaluation import metrics_run

    return metrics_run(load_agent(path), episodes=settings["episodes"], seed=settings["seed"],
                       **settings["env_options"]).to_dict()


def served_episodes(client, submission_id: int, evaluation_id: int) -> list[dict]:
    items: list[dict] = []
    while True:
        page = client.get(f"/api/submissions/{submission_id}/episodes",
                          params={"evaluation_id": evaluation_id, "offset": len(items), "limit": 1000}).json()
        items += page["items"]
        if len(items) >= page["total"] or not page["items"]:
            return items


def check_uploads(uploads: list[Upload], final: dict[int, dict]) -> list[str]:
    """Good uploads ready and evaluated; broken ones refused with a reason (at upload or by validation)."""
    failures = []
    for upload in uploads:
        served = final.get(upload.submission_id) if upload.submission_id else None
        if upload.broken:
            refused_at_upload = upload.code is not None and 400 <= upload.code < 500 and upload.detail
            rejected = served is not None and served["status"] == "rejected" and served["error"]
            if not (refused_at_upload or rejected):
                failures.append(f"broken {upload.name} ({upload.file.name}) not refused with a reason: "
                                f"{upload.code} {upload.detail[:200]} {served and (served['status'], served['error'])}")
        elif upload.code != 201 or served is None:
            failures.append(f"{upload.name} ({upload.file.name}) not accepted: {upload.code} {upload.detail[:200]}")
        elif served["status"] != "ready" or (served["evaluation"] or {}).get("status") != "done":
            failures.append(f"{upload.name} ({upload.file.name}) is {served['status']}, evaluation "
                            f"{(served['evaluation'] or {}).get('status')}: {served['error']}")
    return failures


def check_submissions(uploads: list[Upload], listing: list[dict]) -> list[str]:
    """One submission per accepted upload, none for a refused one."""
    names = Counter(s["name"] for s in listing if s["owner"] != "baselines")
    accepted = {u.name for u in uploads if u.code == 201}
    failures = [f"{name}: {count} submissions" for name, count in names.items() if count != 1 or name not in accepted]
    failures += [f"{name}: accepted but missing" for name in accepted - set(names)]
    return failures


def check_jobs(database_url: str, final: dict[int, dict], race_ids: list[int]) -> tuple[list[str], Counter]:
    """From the database: nothing queued or running, nothing failed; per submission one validation
    done, and one evaluation (job and row) done if it is ready; per heat one race job done."""
    from sqlalchemy import select

    from league.server.db.models import Evaluation, Job
    from league.server.db.session import make_engine, make_sessionmaker

    engine = make_engine(database_url)
    try:
        with make_sessionmaker(engine)() as session:
            jobs = session.execute(select(Job.id, Job.kind, Job.status, Job.submission_id, Job.race_id,
                                          Job.attempts, Job.error)).all()
            evaluations = Counter(session.scalars(select(Evaluation.submission_id)))
    finally:
        engine.dispose()
    failures = [f"job {j.id} ({j.kind}) is {j.status}: {j.error}" for j in jobs if j.status != "done"]
    per_subject = defaultdict(list)
    for job in jobs:
        per_subject[job.kind, job.submission_id or job.race_id].append(job.status)
    for submission_id, served in final.items():
        expected = {"validate": ["done"], "evaluate": ["done"] if served["status"] == "ready" else []}
        for kind, statuses in expected.items():
            if per_subject.get((kind, submission_id), []) != statuses:
                failures.append(f"submission {submission_id}: {kind} jobs {per_subject.get((kind, submission_id))}")
        if evaluations[submission_id] != len(expected["evaluate"]):
            failures.append(f"submission {submission_id}: {evaluations[submission_id]} evaluations")
    failures += [f"race {race_id}: race jobs {per_subject.get(('race', race_id))}" for race_id in race_ids
                 if per_subject.get(("race", race_id)) != ["done"]]
    return failures, Counter(job.attempts for job in jobs)


def check_results(league: League, uploads: list[Upload], final: dict[int, dict], settings: dict) -> list[str]:
    """Every evaluation equals metrics_run of its file here: totals and every episode, exactly."""
    import hashlib

    ready = [u for u in uploads if u.submission_id and final[u.submission_id]["status"] == "ready"]
    files = sorted({u.file for u in ready})
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn")) as pool:
        local = dict(zip(files, pool.map(local_figures, map(str, files), [settings] * len(files))))
    failures = []
    with league.client() as client:
        for upload in ready:
            served, expected = final[upload.submission_id], local[upload.file]
            evaluation = served["evaluation"]
            if served["sha256"] != hashlib.sha256(upload.file.read_bytes()).hexdigest():
                failures.append(f"{upload.name}: stored file differs from the uploaded one")
            if evaluation["settings"] != settings:
                failures.append(f"{upload.name}: evaluated with {evaluation['settings']}, the course says {settings}")
            totals = {key: evaluation[key] for key in FIGURES}
            if totals != {key: expected[key] for key in FIGURES}:
                failures.append(f"{upload.name} ({upload.file.name}): {totals} != local "
                                f"{ {key: expected[key] for key in FIGURES} }")
            episodes = served_episodes(client, upload.submission_id, evaluation["id"])
            if [e.pop("index") for e in episodes] != list(range(len(episodes))) or episodes != expected["episodes"]:
                failures.append(f"{upload.name} ({upload.file.name}): episodes differ from the local run")
    return failures


def check_round(summary: dict, students: int, active: set[int]) -> list[str]:
    entrants = [s for heat in summary["heats"] for s in heat]
    failures = []
    if summary["status"] != "done":
        failures.append(f"the round is {summary['status']}")
    if len(entrants) != students or set(entrants) != active:
        failures.append(f"the round's {len(entrants)} entrants ({len(set(entrants))} different) are not the "
                        f"{students} students' active agents")
    for race in summary["races"]:
        if race["status"] != "done" or len(race["classification"] or []) != len(race["entrants"]):
            failures.append(f"race {race['id']} is {race['status']}: {race['error']}")
    return failures


# --------------------------------------------------------------------------- figures


PHASES = ("rush", "idle", "round")  # when the pollers' answers came


@dataclass
class RushFigures:
    """What a rush measured, and what its checks found (`failures`: none when all passed)."""

    uploads: int
    accepted: int  # answered 201
    broken: int
    refused_at_upload: int  # broken ones answered 4xx
    ready: int  # submissions validated
    rejected: int  # submissions refused by validation
    upload_s: float  # first upload sent -> last one answered
    drain_s: float  # last upload answered -> queue empty
    latencies: dict[str, dict[str, dict[str, float]]]  # "status"/"leaderboard" -> phase -> p50, p99 (ms), answers
    round_s: float  # POST .../rounds -> the round done
    round_waits: HeatWaits  # where the round's time went besides racing
    heats_s: float  # the heats' run times (claimed -> finished), summed
    heats: int
    cars: int
    attempts: dict[int, int]  # jobs by how many attempts they took
    faults: dict[str, float] = field(default_factory=dict)  # what -> seconds from the first upload
    polls_refused: int = 0  # polls refused or cut while the faults were injected
    failures: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.failures


def latency_figures(pollers: Pollers) -> dict[str, dict[str, dict[str, float]]]:
    return {what: {phase: {**percentiles_ms(pollers.latencies[what, phase]),
                           "answers": len(pollers.latencies[what, phase])} for phase in PHASES}
            for what in ("status", "leaderboard")}


def percentiles(figures: dict[str, float]) -> str:
    if not figures["answers"]:
        return "no answers"
    return f"p50 {figures['p50']:.1f} ms, p99 {figures['p99']:.1f} ms ({figures['answers']} answers)"


def report(figures: RushFigures) -> None:
    f = figures
    print(f"  {f.uploads} uploads in {f.upload_s:.1f} s: {f.accepted} accepted, {f.broken} broken "
          f"({f.refused_at_upload} refused at upload); {f.ready} ready, {f.rejected} rejected")
    if f.faults:
        print("  faults: " + ", ".join(f"{what} at {at:.1f} s" for what, at in f.faults.items())
              + f"; {f.polls_refused} polls refused or cut meanwhile")
    print(f"  last upload -> queue empty: {f.drain_s:.1f} s (target <= {QUEUE_TARGET_S:g} s: "
          f"{'ok' if f.drain_s <= QUEUE_TARGET_S else 'OVER TARGET'})")
    for what, phases in f.latencies.items():
        p99 = phases["rush"]["p99"]
        verdict = "ok" if p99 <= P99_TARGET_MS else "OVER TARGET"
        print(f"  GET {what}: during the rush {percentiles(phases['rush'])} (target p99 <= {P99_TARGET_MS:g} ms: "
              f"{verdict}); idle {percentiles(phases['idle'])}; during the round {percentiles(phases['round'])}")
    w = f.round_waits
    print(f"  championship round of {f.heats} heats ({f.cars} cars): {f.round_s:.1f} s from POST to done; the heats "
          f"ran {f.heats_s:.1f} s in all (claimed -> finished), the busiest worker's {w.busiest_s:.1f} s; waiting for "
          f"the queue: first heat claimed after {w.first_claim_s:.2f} s, workers idle between heats {w.idle_s:.2f} s "
          f"in all; the last heat finished {w.tail_s:.1f} s after the other worker's")
    print(f"  jobs by attempts: {dict(sorted(f.attempts.items()))}")
    print(checks_line(f.failures, "uploads accounted for, one submission each, no job lost, stuck, failed or done "
                                  "twice, results equal to local metrics_run, the round complete"), flush=True)


def unexpected_errors(pollers: Pollers, events: dict[str, float]) -> list[str]:
    """Poll errors other than while the API restarted (1 s of grace)."""
    down, up = events.get("API down", math.inf), events.get("API up", -math.inf)
    return [f"GET {what} at {sent:.1f}: {status}" for sent, what, status in pollers.errors
            if not down - 1 <= sent <= up + 1]


# --------------------------------------------------------------------------- main


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog="\n".join(__doc__.splitlines()[4:]),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--backend", choices=["sqlite", "postgres"], default="sqlite",
                        help="sqlite: an SQLite database; postgres: the local PostgreSQL (LEAGUE_BENCH_PG)")
    parser.add_argument("--students", type=int, default=200)
    parser.add_argument("--uploads", type=int, default=600)
    parser.add_argument("--window-s", type=float, default=300.0, help="the uploads are spread over this time")
    parser.add_argument("--episodes", type=int, default=100, help="episodes of the course's evaluations")
    parser.add_argument("--seed", type=int, default=0, help="the course's evaluation seed (and the plan's draws)")
    parser.add_argument("--distinct", type=int, default=48, help="different working agent files (8 kinds)")
    parser.add_argument("--status-clients", type=int, default=50, help="students polling their status every 2 s")
    parser.add_argument("--board-clients", type=int, default=100, help="clients polling the leaderboard every 5 s")
    parser.add_argument("--idle-s", type=float, default=10.0, help="polling after the queue emptied (idle figures)")
    parser.add_argument("--faults", action="store_true",
                        help="halfway through: kill -9 a worker running a job, restart the API, then start a "
                             "worker again")
    args = parser.parse_args(argv)
    if args.uploads < args.students:
        parser.error("every student uploads at least once: --uploads must be >= --students")
    return args


def header(args: argparse.Namespace) -> str:
    return (f"{machine()}; {args.backend}: {args.students} students, {args.uploads} uploads over {args.window_s:g} s, "
            f"{args.episodes}-episode evaluations, 2 workers{', faults' if args.faults else ''}")


def measure(args: argparse.Namespace) -> RushFigures:
    """The rush of `args` (parse()'s options) on a league of its own, stopped and removed afterwards."""
    settings = {**course_settings(students=args.students, uploads=args.uploads, episodes=args.episodes, seed=args.seed),
                # a killed worker's job goes elsewhere within seconds, not the default minute
                "LEAGUE_HEARTBEAT_INTERVAL_S": "1", "LEAGUE_LEASE_TIMEOUT_S": "8", "LEAGUE_REAPER_INTERVAL_S": "2"}
    with course_league(args.backend, "league-rush-", **settings) as (league, folder, database_url):
        uploads = plan(args.students, args.uploads, course_files(folder / "files", min(args.distinct, args.uploads)),
                       broken_files(folder / "files"), args.seed)
        return rush(league, args, uploads, database_url)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    print(header(args), flush=True)
    figures = measure(args)
    report(figures)
    return 0 if figures.passed else 1


def rush(league: League, args: argparse.Namespace, uploads: list[Upload], database_url: str) -> RushFigures:
    with league.client() as instructor:
        tokens = enrol(instructor, student_names(args.students))
        course = instructor.get("/api/settings/evaluation").json()
    drain_timeout = 300 + args.uploads * args.episodes * 0.05
    wait_queue_empty(league, drain_timeout)  # the baselines' evaluations: before the rush
    uploader = Uploader(league, tokens, uploads, args.window_s)
    pollers = Pollers(league.url, args.seed)
    pollers.add("status", [status_client(uploader, tokens, (c * args.students) // args.status_clients)
                           for c in range(args.status_clients)], STATUS_PERIOD_S)
    pollers.add("leaderboard", [lambda: ("/api/leaderboard", None)] * args.board_clients, BOARD_PERIOD_S)
    events: dict[str, float] = {}
    try:
        pollers.phase = "rush"
        begin = time.perf_counter()
        faults = threading.Thread(target=inject_faults, args=(league, begin + args.window_s / 2, events))
        if args.faults:
            faults.start()
        uploader.run()
        last_upload = max(u.answered_at for u in uploads)
        if args.faults:
            faults.join()
        emptied = wait_queue_empty(league, drain_timeout)
        pollers.phase = "idle"
        time.sleep(args.idle_s)
        pollers.phase = "round"
        round_s, summary = run_round(league, args.seed, args.students)
    finally:
        pollers.close()
    with league.client() as instructor:
        listing = instructor.get("/api/submissions", params={"all": True}).json()
    final = {s["id"]: s for s in listing if s["owner"] != "baselines"}

    failures = unexpected_errors(pollers, events)
    failures += check_uploads(uploads, final)
    failures += check_submissions(uploads, listing)
    job_failures, attempts = check_jobs(database_url, final, summary["race_ids"])
    failures += job_failures
    active = {s["id"] for s in final.values() if s["active"]}
    failures += check_round(summary, args.students, active)
    failures += check_results(league, uploads, final, course)
    return RushFigures(
        uploads=len(uploads), accepted=sum(u.code == 201 for u in uploads), broken=sum(u.broken for u in uploads),
        refused_at_upload=sum(u.broken and u.code != 201 for u in uploads),
        ready=sum(s["status"] == "ready" for s in final.values()),
        rejected=sum(s["status"] == "rejected" for s in final.values()),
        upload_s=last_upload - begin, drain_s=emptied - last_upload, latencies=latency_figures(pollers),
        round_s=round_s, round_waits=summary["waits"], heats_s=summary["heats_s"], heats=len(summary["race_ids"]),
        cars=sum(map(len, summary["heats"])),
        attempts=dict(attempts), faults={what: at - begin for what, at in events.items()},
        polls_refused=len(pollers.errors) if events else 0, failures=failures)


def status_client(uploader: Uploader, tokens: list[str], student: int):
    def target() -> tuple[str, str] | None:
        submission_id = uploader.latest.get(student)
        return None if submission_id is None else (f"/api/submissions/{submission_id}", tokens[student])
    return target


if __name__ == "__main__":
    run_script(main)

"""The student's side of a league server from a terminal: `league login`, `check`, `submit`,
`submissions`, `leaderboard`, `standings`, `race-server`; and the instructor's `integrity`,
`championships` and more (what the instructor console does, a command does too).

A small client of the server's HTTP API (httpx). The server and token come from --server/--token,
else LEAGUE_SERVER/LEAGUE_TOKEN, else what `league login` stored in the user's config directory
(platformdirs; the file is readable by its owner only). `league check` runs the server's own
validation (league.validation: the static checks, the checked load and dry run, the timed calls,
each within the server's CPU budgets) on this machine, against the configured server's limits,
else (no server, or one that cannot be reached) the league's defaults. Never imports league.server.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from league.command import add_env_switches, env_options
from league.exit_codes import (
    CLIENT_EXIT_CODES, EXIT_AUTH, EXIT_ERROR, EXIT_OK, EXIT_REFUSED, EXIT_REJECTED, EXIT_TIMEOUT, EXIT_UNREACHABLE,
)
from league.spreadsheet import csv_text

if TYPE_CHECKING:
    from league.validation.files import Upload
    from league.validation.limits import SandboxLimits
    from league.validation.report import ValidationReport

TERMINAL = {"ready", "rejected", "failed"}
STAGES = ["pending", "validating", "ready", "evaluation queued", "evaluation running", "done"]


class ClientError(Exception):
    """One line for the user and the exit status it means."""

    def __init__(self, message: str, exit_code: int):
        super().__init__(message)
        self.exit_code = exit_code


# --------------------------------------------------------------------------- configuration


def config_path() -> Path:
    from platformdirs import user_config_dir

    return Path(user_config_dir("microracer-league")) / "client.json"


@dataclass(frozen=True)
class Connection:
    server: str
    token: str | None


def connection(args: argparse.Namespace, need_token: bool = True) -> Connection:
    stored = {}
    path = config_path()
    if path.is_file():
        stored = json.loads(path.read_text())
    server = args.server or os.environ.get("LEAGUE_SERVER") or stored.get("server")
    token = args.token or os.environ.get("LEAGUE_TOKEN") or stored.get("token")
    if not server:
        raise ClientError("no server: run `league login --server URL` or give --server URL (or LEAGUE_SERVER)",
                          EXIT_ERROR)
    if need_token and not token:
        raise ClientError("no token: run `league login` or give --token TOKEN (or LEAGUE_TOKEN)", EXIT_AUTH)
    return Connection(server.rstrip("/"), token)


def store_login(server: str, token: str) -> Path:
    """Write the server and token for the next commands, readable by this user only."""
    path = config_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(".tmp")
    temporary.unlink(missing_ok=True)
    with os.fdopen(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600), "w") as handle:
        json.dump({"server": server, "token": token}, handle)
    os.replace(temporary, path)
    return path


# --------------------------------------------------------------------------- HTTP


class Api:
    """The server's API; every failure becomes a ClientError with the server's own words."""

    def __init__(self, conn: Connection, timeout: float = 60):
        import httpx

        self.conn = conn
        headers = {"Authorization": f"Bearer {conn.token}"} if conn.token else {}
        self.http = httpx.Client(base_url=conn.server, headers=headers, timeout=timeout)

    def __enter__(self) -> Api:
        return self

    def __exit__(self, *exc_info) -> None:
        self.http.close()

    def call(self, method: str, path: str, **kwargs):
        import httpx

        try:
            response = self.http.request(method, path, **kwargs)
        except httpx.HTTPError as error:
            raise ClientError(f"cannot reach the league server at {self.conn.server}: {error}",
                              EXIT_UNREACHABLE) from error
        if response.is_success:
            return response.json() if "json" in response.headers.get("content-type", "") else response.text
        detail = _detail(response)
        if response.status_code == 401:  # the server says why (replaced, revoked) and whom to ask
            raise ClientError(f"the server refused the token: {detail}; once you have a new one: "
                              f"league login --server {self.conn.server}", EXIT_AUTH)
        if response.status_code == 403:
            raise ClientError(f"the server refused: {detail}", EXIT_AUTH)
        if response.status_code >= 500:
            raise ClientError(f"the server failed ({response.status_code}): {detail}", EXIT_UNREACHABLE)
        raise ClientError(f"the server refused: {detail}", EXIT_REFUSED)

    def get(self, path: str, **params):
        return self.call("GET", path, params=params or None)


def _detail(response) -> str:
    try:
        detail = response.json().get("detail")
    except (ValueError, AttributeError):
        detail = None
    return detail if isinstance(detail, str) and detail else f"{response.status_code} {response.reason_phrase}"


# --------------------------------------------------------------------------- check


def check_limits(api: Api | None, *, offline_ok: bool = False) -> tuple[SandboxLimits, int]:
    """The limits uploads are validated with and the largest upload in bytes: the configured
    server's (GET /api/settings/limits), else the league's defaults. With `offline_ok`, a server
    that cannot be reached is said on stderr and the defaults are used."""
    from league.validation.files import MB
    from league.validation.limits import MAX_UPLOAD_MB, SandboxLimits

    if api is not None:
        try:
            served = api.get("/api/settings/limits")
        except ClientError as error:
            if not offline_ok or error.exit_code != EXIT_UNREACHABLE:
                raise
            print(f"{error}; checking against the league's default limits", file=sys.stderr)
        else:
            limits = SandboxLimits(memory_mb=served["sandbox_memory_mb"],
                                   step_deadline_s=served["step_deadline_ms"] / 1000,
                                   first_call_allowance_s=served["first_call_allowance_ms"] / 1000,
                                   run_cpu_s=served["run_cpu_s"], load_cpu_s=served["load_cpu_s"])
            return limits, served["max_upload_bytes"]
    return SandboxLimits(), int(MAX_UPLOAD_MB * MB)


def check_files(paths: list[Path], limits: SandboxLimits, max_bytes: int):
    """(path, upload, report) for each of `paths`, in order: what would be uploaded (None if the file
    is refused before that) and the server's verdict on it (league.validation.local, run here)."""
    from league.validation.checks import ModelRejected
    from league.validation.files import read_upload
    from league.validation.report import ValidationReport

    for path in paths:
        if not path.exists():
            raise ClientError(f"no such file: {path}", EXIT_ERROR)
        try:
            upload = read_upload(path, max_bytes)
        except ModelRejected as refusal:
            yield path, None, ValidationReport(False, None, refusal.reason, "")
            continue
        yield path, upload, check_upload(upload, limits)


def check_upload(upload: Upload, limits: SandboxLimits) -> ValidationReport:
    """The verdict on an upload, checked here as the file the server would get."""
    from league.validation.local import check_model, missing_runtime

    missing = missing_runtime(upload.kind)
    if missing:
        raise ClientError(missing, EXIT_ERROR)
    with tempfile.TemporaryDirectory(prefix="league-upload-") as folder:
        model = Path(folder) / upload.name
        model.write_bytes(upload.data)
        return check_model(model, limits)


def check_report(path: Path, upload: Upload | None, report: ValidationReport, limits: SandboxLimits) -> str:
    if not report.ok:
        return f"{path.name}: the server would reject it: {report.error}"  # a timing's figures are in it
    packed = (f"; its weights in {', '.join(upload.packed)} are packed in (`league submit` uploads one file)"
              if upload.packed else "")
    return (f"{path.name}: the server would accept it: observation size {report.obs_dim}, "
            f"{report.cpu_ms_per_observation:.2f} ms of CPU per observation "
            f"(limit {limits.step_deadline_s * 1000:g} ms){packed}")


def run_check(args: argparse.Namespace) -> int:
    """One line per file, in order; exit 0 only if the server would accept every one."""
    api = _optional_api(args)
    accepted = True
    try:
        limits, max_bytes = check_limits(api, offline_ok=True)
        if args.step_deadline_ms is not None:
            limits = replace(limits, step_deadline_s=args.step_deadline_ms / 1000)
        for path, upload, report in check_files([Path(file) for file in args.files], limits, max_bytes):
            print(check_report(path, upload, report, limits), flush=True)
            if args.log and report.log:
                print(report.log, file=sys.stderr, flush=True)
            accepted = accepted and report.ok
    finally:
        if api is not None:
            api.http.close()
    return EXIT_OK if accepted else EXIT_REJECTED


def _optional_api(args: argparse.Namespace) -> Api | None:
    """The configured server, if any (its limits); `league check` works without one, and without
    the client extra (then a server named on the command line or in LEAGUE_SERVER is not asked)."""
    try:
        return Api(connection(args, need_token=False))
    except ClientError:
        return None
    except ImportError as error:
        if args.server or os.environ.get("LEAGUE_SERVER"):
            print(f"the server's limits need the client extra ({error.name} is not installed): checking against "
                  f"the league's default limits", file=sys.stderr)
        return None


# --------------------------------------------------------------------------- commands


def run_login(args: argparse.Namespace) -> int:
    server = args.server or os.environ.get("LEAGUE_SERVER")
    if not server:
        raise ClientError("say which server: league login --server URL", EXIT_ERROR)
    token = args.token or os.environ.get("LEAGUE_TOKEN")
    if not token:
        import getpass

        token = getpass.getpass("API token (from your instructor): ").strip()
    with Api(Connection(server.rstrip("/"), token)) as api:
        me = api.get("/api/users/me")
    path = store_login(server.rstrip("/"), token)
    print(f"logged in to {server} as {me['name']} ({me['role']}); saved in {path}")
    return EXIT_OK


def run_submit(args: argparse.Namespace) -> int:
    path = Path(args.file)
    with Api(connection(args)) as api:
        assignment = args.assignment or only_open_assignment(api)
        upload = checked_upload(api, path) if not args.no_check else as_is(path)
        if upload is None:
            return EXIT_REJECTED
        data = {"name": args.name} if args.name else {}
        if assignment:
            data["assignment"] = assignment
        created = api.call("POST", "/api/submissions", files={"file": (upload.name, upload.data)}, data=data)
        late = api.get(f"/api/submissions/{created['id']}")["late"]  # the upload's answer is {id, status} only
        print(f"submission {created['id']}: {created['status']}{LATE_NOTE if late else ''}", file=sys.stderr)
        if not args.wait:
            print(created["id"])
            return EXIT_OK
        submission = wait_settled(api, created["id"], args.timeout, progress=not args.no_progress)
        evaluation = submission.get("evaluation")
        if evaluation and evaluation["status"] == "done":  # the status answer links to its episodes
            evaluation["episodes"] = all_episodes(api, submission["links"]["episodes"])
    return report_submission(submission, args.json)


def only_open_assignment(api: Api) -> str | None:
    """The name of the only assignment open to the user's uploads (said on stderr); several: a usage
    error listing them, before anything is checked or uploaded; none: None, the server says why."""
    open_ = [a for a in api.get("/api/assignments") if a["state"] in ("open", "late")]
    if len(open_) > 1:
        names = ", ".join(a["name"] for a in open_)
        raise ClientError(f"several assignments are open to you: {names}; say which with --assignment NAME, e.g. "
                          f"league submit FILE --assignment {shell_word(open_[0]['name'])}", EXIT_ERROR)
    if open_:
        print(f"for the assignment {open_[0]['name']} (the only one open to you)", file=sys.stderr)
        return open_[0]["name"]
    return None


def shell_word(text: str) -> str:
    import shlex

    return shlex.quote(text)


def checked_upload(api: Api, path: Path) -> Upload | None:
    """What `league submit` uploads once `league check` accepts it (its verdict on stderr), else None."""
    limits, max_bytes = check_limits(api)
    [(_, upload, report)] = check_files([path], limits, max_bytes)
    print(check_report(path, upload, report, limits), file=sys.stderr)
    return upload if report.ok else None


def as_is(path: Path) -> Upload:
    """The upload of `--no-check`: the file, its external data packed in when that works."""
    from league.validation.checks import ModelRejected
    from league.validation.files import Upload, model_kind_of, read_upload

    if not path.is_file():
        raise ClientError(f"no such file: {path}", EXIT_ERROR)
    try:
        return read_upload(path, max_bytes=path.stat().st_size + 2**40)
    except ModelRejected:  # the server says why
        return Upload(path.name, model_kind_of(path.name) or "", path.read_bytes())


def all_episodes(api: Api, link: str) -> list[dict]:
    """Every episode of an evaluation, from its paged endpoint (`link`: the status answer's)."""
    import httpx

    url, episodes = httpx.URL(link), []
    while True:
        page = api.get(url.path, **dict(url.params), offset=len(episodes), limit=EPISODE_PAGE)
        episodes += page["items"]
        if len(episodes) >= page["total"] or not page["items"]:
            return episodes


def stage(submission: dict) -> str:
    evaluation = submission.get("evaluation") or {}
    if submission["status"] != "ready":
        return submission["status"]
    done = "done" if evaluation.get("status") == "done" else f"evaluation {evaluation.get('status', 'queued')}"
    return f"{done} (stale: other settings)" if evaluation.get("stale") else done


def settled(submission: dict) -> bool:
    evaluation = submission.get("evaluation") or {}
    return submission["status"] in TERMINAL and (submission["status"] != "ready"
                                                 or evaluation.get("status") in ("done", "failed"))


def wait_settled(api: Api, submission_id: int, timeout: float, progress: bool = True) -> dict:
    """Poll the submission until validated and evaluated, with a bar of its stages (it counts
    stages, not episodes: the server tells an evaluation's figures when it is done)."""
    from tqdm import tqdm

    deadline = time.monotonic() + timeout
    with tqdm(total=len(STAGES), disable=not progress, file=sys.stderr,
              bar_format="{desc} {bar} stage {n}/{total}") as bar:
        while True:
            submission = api.get(f"/api/submissions/{submission_id}")
            now = stage(submission)
            episodes = (submission.get("evaluation") or {}).get("settings", {}).get("episodes")
            bar.set_description_str(f"submission {submission_id}: {now}"
                                    + (f" ({episodes} episodes)" if now.startswith("evaluation") and episodes else ""))
            if now in STAGES:
                bar.update(STAGES.index(now) + 1 - bar.n)
            if settled(submission):
                return submission
            if time.monotonic() > deadline:
                raise ClientError(f"submission {submission_id} is still {now} after {timeout:g} s; "
                                  f"see `league submissions`", EXIT_TIMEOUT)
            time.sleep(1.0)


EPISODE_PAGE = 1000  # the most the server gives in one page
LATE_NOTE = "; late (after your due time): the late penalty applies if it is your final"


def report_submission(submission: dict, as_json: bool) -> int:
    from league.evaluation import MetricsResult

    evaluation = submission.get("evaluation")
    if as_json:
        print(json.dumps(submission, indent=2))
    elif submission["status"] != "ready":
        print(f"submission {submission['id']} was {submission['status']}: {submission['error']}")
    elif evaluation["status"] != "done":
        print(f"submission {submission['id']} is ready, but its evaluation failed: {evaluation['error']}")
    else:
        # the server's record, as `league evaluate` prints its own: the same result key, the same tracks
        record = {**evaluation["settings"], "agent": submission["name"], "versions": evaluation.get("versions"),
                  "result_key": evaluation.get("result_key")}
        result = MetricsResult.from_dict({"episodes": evaluation["episodes"], "settings": record})
        print(f"submission {submission['id']} is ready\n{result.table()}")
    if submission["late"] and not as_json:
        print(f"submission {submission['id']} was uploaded late (after your due time): the late penalty applies "
              "if it is your final")
    ok = submission["status"] == "ready" and evaluation and evaluation["status"] == "done"
    return EXIT_OK if ok else EXIT_REJECTED


def run_submissions(args: argparse.Namespace) -> int:
    with Api(connection(args)) as api:
        rows = api.get("/api/submissions")
    table = [[s["id"], s["name"], stage(s), "late" if s["late"] else "", *_figures(s.get("evaluation")),
              s["error"] or ""] for s in rows]
    _print_table(["id", "agent", "status", "late", "completed", "mean return", "mean speed", "error"], table, args.csv)
    return EXIT_OK


def _figures(evaluation: dict | None) -> list:
    if not evaluation or evaluation["status"] != "done":
        return ["", "", ""]
    return [f"{evaluation['completed']}/{evaluation['episodes_total']}", f"{evaluation['mean_return']:.3f}",
            f"{evaluation['mean_speed']:.3f}"]


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
    _print_table(["rank", "student", "agent", "id", "completed", "mean return", "mean speed", "rating"],
                 [["stale" if r.get("stale") else r["rank"], r["owner"], r["name"], r["submission_id"],
                   f"{r['completed']}/{r['episodes']}",
                   f"{r['mean_return']:.3f}", f"{r['mean_speed']:.3f}",
                   "" if r["rating"] is None else f"{r['rating']:.2f}"] for r in rows], False)
    return EXIT_OK


def run_standings(args: argparse.Namespace) -> int:
    with Api(connection(args, need_token=args.csv)) as api:
        championship = championship_id(api, args.championship)
        if args.csv:  # instructors: the grades
            sys.stdout.write(api.get(f"/api/championships/{championship}/standings.csv"))
            return EXIT_OK
        rows = api.get(f"/api/championships/{championship}/standings", size=100)["items"]
    _print_table(["rank", "student", "agent", "id", "points", "wins", "heats", "rating"],
                 [[r["rank"], r["owner"], r["name"], r["submission_id"], r["points"], r["wins"], len(r["finishes"]),
                   f"{r['rating']:.2f}"] for r in rows], False)
    return EXIT_OK


def run_championships(args: argparse.Namespace) -> int:
    """The console's championship panel from a terminal: list, create, run a round and watch it, standings."""
    if args.action == "list":
        with Api(connection(args)) as api:
            championships = api.get("/api/championships")
        _print_table(["id", "championship", "rounds", "cars per heat", "assignment", "baselines"],
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
    _print_table(["round", "status", "heats done", "races", "created"],
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

    deadline = time.monotonic() + timeout
    path = f"/api/championships/{championship}/rounds/{number}"
    with tqdm(total=None, disable=not progress, file=sys.stderr, unit="heat",
              bar_format="{desc} {bar} {n}/{total} heats") as bar:
        while True:
            round_ = api.get(path)
            bar.total = round_["heats_total"]
            bar.set_description_str(f"round {number}: {round_['status']}")
            bar.update(round_["heats_done"] - bar.n)
            if round_["status"] in ("done", "failed"):
                return round_
            if time.monotonic() > deadline:
                raise ClientError(f"round {number} is still {round_['status']} after {timeout:g} s "
                                  f"({round_['heats_done']}/{round_['heats_total']} heats done); follow it with "
                                  f"`league championships rounds {championship}`", EXIT_TIMEOUT)
            time.sleep(1.0)


def report_round(round_: dict) -> int:
    heats = f"{round_['heats_done']}/{round_['heats_total']} heats done"
    if round_["status"] == "failed":
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


# --------------------------------------------------------------------------- assignments


def find_assignment(api: Api, wanted: str) -> dict:
    """The assignment `wanted` names (its name, any case, or its id)."""
    assignments = api.get("/api/assignments")
    found = [a for a in assignments if a["name"] == wanted or str(a["id"]) == wanted] or [
        a for a in assignments if a["name"].casefold() == wanted.casefold()]
    if len(found) == 1:
        return found[0]
    listing = ", ".join(a["name"] for a in assignments) or "none yet"
    raise ClientError(f"no assignment named {wanted!r}; the assignments: {listing}", EXIT_ERROR)


def local_time(text: str | None) -> str:
    """A UTC time of the API in this machine's time zone, with the zone: 2026-12-02 00:59 CET."""
    if not text:
        return ""
    from datetime import datetime

    return datetime.fromisoformat(text).astimezone().strftime("%Y-%m-%d %H:%M %Z")


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
    _print_table(["id", "assignment", "state", "opens", "due (yours)", "time left", "late until", "final",
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
    _print_table(["group", "kind", "distance", "owner", "id", "agent", "file"],
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
    _print_table(["id", "kind", "status", "submission", "race", "attempts", "created", "error"],
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
    _print_table(["at", "who", "action", "target", "details"],
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


def run_grades(args: argparse.Namespace) -> int:
    """Instructors: the grades as CSV on standard output (an assignment's, or the course's); with
    --set-rubric, set the assignment's rubric (and say what changed); with --check, how Canvas will
    match the Canvas file's students. Students: their own grade, once published."""
    with Api(connection(args)) as api:
        me = api.get("/api/users/me")
        assignment = find_assignment(api, args.assignment) if args.assignment else None
        if me["role"] != "instructor":
            if assignment is None:
                raise ClientError("league grades ASSIGNMENT: which assignment?", EXIT_ERROR)
            return print_my_grade(api.get(f"/api/assignments/{assignment['id']}/grades/me"))
        if args.check and args.format != "canvas":
            raise ClientError("--check says how Canvas will match the file's students: league grades "
                              "[ASSIGNMENT] --format canvas --check", EXIT_ERROR)
        if args.set_rubric:
            if assignment is None:
                raise ClientError("league grades ASSIGNMENT --set-rubric FILE: which assignment?", EXIT_ERROR)
            saved = api.call("PUT", f"/api/assignments/{assignment['id']}/rubric",
                             json=read_rubric_file(args.set_rubric))
            print(rubric_change(assignment["name"], assignment["rubric"], saved["rubric"]))
            return EXIT_OK
        path = f"/api/assignments/{assignment['id']}/grades" if assignment else "/api/grades"
        if args.check:
            print(api.get(f"{path}/canvas-match")["summary"])
            return EXIT_OK
        sys.stdout.write(api.get(f"{path}.csv", format=args.format, identifier=args.identifier))
        sys.stdout.flush()
        if args.format == "moodle":
            warn_unidentified(api.get("/api/users"), args.identifier)
        elif args.format == "canvas":
            print(api.get(f"{path}/canvas-match")["summary"], file=sys.stderr)
    return EXIT_OK


def rubric_change(name: str, old: dict | None, new: dict) -> str:
    """What --set-rubric changed, in one line: the rubric before and after (compact JSON)."""
    def compact(rubric: dict | None) -> str:
        return json.dumps(rubric, separators=(",", ":")) if rubric else "none"

    if old == new:
        return f"{name}: rubric unchanged ({compact(new)})"
    return f"{name}: rubric set to {compact(new)} (was {compact(old)}); `league grades {name!r}` prints the grades"


def read_rubric_file(name: str) -> dict:
    text = sys.stdin.read() if name == "-" else Path(name).read_text(encoding="utf-8")
    try:
        return json.loads(text)
    except ValueError as error:
        raise ClientError(f"{name}: not JSON ({error}); see the server README, Grades, for examples",
                          EXIT_ERROR) from None


def warn_unidentified(users: list[dict], identifier: str) -> None:
    """Name the students the Moodle file leaves out: those without the identifier it matches by."""
    key = "email" if identifier == "email" else "student_id"
    missing = [u["name"] for u in users if u["role"] == "student" and not u.get(key)]
    if missing:
        print(f"left out of the Moodle file, without {'an email' if key == 'email' else 'a student id'}: "
              f"{', '.join(missing)} (upload the roster with that column, or use the other --identifier)",
              file=sys.stderr)


def print_my_grade(grade: dict) -> int:
    if grade["points"] is None:
        print(f"{grade['assignment']}: no grade yet ({grade['status']})")
        return EXIT_OK
    rank = f", rank {grade['rank']} of {grade['students']}" if grade["rank"] else ""
    late = f", late: x{grade['penalty']:g}" if grade["late"] else ""
    print(f"{grade['assignment']}: {grade['points']:g} / {grade['max_points']:g} points{rank}{late}")
    if grade.get("note"):  # its private result changed after the publication (a server before 0018: no key)
        print(f"  changed since the publication: {grade['note']}")
    return EXIT_OK


def run_race_server(args: argparse.Namespace) -> int:
    body = {"submission_ids": args.ids, **({"seed": args.seed} if args.seed is not None else {})}
    with Api(connection(args)) as api:
        created = api.call("POST", "/api/races", json=body)
        print(f"race {created['id']}: {api.conn.server}/races/{created['id']}", file=sys.stderr)
        deadline = time.monotonic() + args.timeout
        race = api.get(f"/api/races/{created['id']}")
        while race["status"] not in ("done", "failed"):
            if time.monotonic() > deadline:
                raise ClientError(f"race {created['id']} is still {race['status']} after {args.timeout:g} s",
                                  EXIT_TIMEOUT)
            time.sleep(1.0)
            race = api.get(f"/api/races/{created['id']}")
        if race["status"] == "failed":
            print(f"race {race['id']} failed: {race['error']}")
            return EXIT_REJECTED
        if args.replay:
            Path(args.replay).write_text(json.dumps(api.get(f"/api/races/{race['id']}/replay")))
    from league.evaluation import classification_table

    rows = [{**row, "name": f"{row['name']} ({row['owner']})"} for row in race["classification"]]  # as the replay
    print(f"race {race['id']} on seed {race['seed']}\n{classification_table(rows)}")
    return EXIT_OK


def _print_table(header: list[str], rows: list[list], as_csv: bool) -> None:
    if as_csv:
        sys.stdout.write(csv_text(header, rows))
        return
    cells = [[str(c) for c in row] for row in [header, *rows]]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]
    for row in cells:
        print("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip())


# --------------------------------------------------------------------------- parser


def add_commands(subparsers) -> None:
    server = argparse.ArgumentParser(add_help=False)
    group = server.add_argument_group("server (else LEAGUE_SERVER / LEAGUE_TOKEN, else what `league login` saved)")
    group.add_argument("--server", metavar="URL", help="the league server, e.g. https://league.example.org")
    group.add_argument("--token", help="your API token")
    formatter = argparse.RawDescriptionHelpFormatter

    def command(name: str, help_: str, run, description: str | None = None):
        parser = subparsers.add_parser(name, parents=[server], help=help_, description=description or help_,
                                       epilog=CLIENT_EXIT_CODES, formatter_class=formatter)
        parser.set_defaults(run=run)
        return parser

    command("login", "check a token with a league server and save both for the next commands", run_login)

    check = command("check", "run the server's checks on model files here, before uploading them", run_check,
                    "The server's own validation, on this machine and without a server: static checks "
                    "(operators, TorchScript rules), loading and a dry run under the memory cap, and the CPU "
                    "time per observation against the limit: the configured server's limits, else (no server, "
                    "or one that cannot be reached) the league's defaults. An ONNX file whose weights torch "
                    "wrote beside it (external data) is checked as `league submit` uploads it: packed into one "
                    "file. One line per file; the exit status is 0 only if the server would accept every file.")
    check.add_argument("files", nargs="+", metavar="FILE", help="ONNX (.onnx) or TorchScript (.pt) files")
    check.add_argument("--log", action="store_true", help="also print what the model's runtime printed")
    check.add_argument("--step-deadline-ms", type=float, metavar="MS",
                       help="check against this CPU time per observation instead of the server's (your margin)")

    submit = command("submit", "upload a model to the league server", run_submit,
                     "Check the file here (as `league check`), upload it (an ONNX file's external data packed "
                     "in), and with --wait follow its validation and evaluation and print the result.")
    submit.add_argument("file", metavar="FILE", help="an ONNX (.onnx) or TorchScript (.pt) file")
    submit.add_argument("--name", help="the submission's name (default: the file name)")
    submit.add_argument("--assignment", metavar="NAME",
                        help="the assignment it is for, by name or id (default: the only one open to you)")
    submit.add_argument("--wait", action="store_true", help="wait until it is validated and evaluated")
    submit.add_argument("--no-check", action="store_true", help="upload without checking the file here first")
    submit.add_argument("--timeout", type=float, default=600, help="seconds --wait waits at most (default 600)")
    submit.add_argument("--json", action="store_true", help="with --wait: print the submission as JSON")
    submit.add_argument("--no-progress", action="store_true", help="hide the progress bar")

    listing = command("submissions", "list your submissions and their results", run_submissions)
    listing.add_argument("--csv", action="store_true", help="print CSV")

    board = command("leaderboard", "print the course leaderboard (or an assignment's board)", run_leaderboard)
    board.add_argument("--csv", action="store_true", help="instructors: the grades, as CSV")
    board.add_argument("--assignment", metavar="NAME", help="that assignment's board (default: the default one's)")
    board.add_argument("--private", action="store_true",
                       help="with --assignment: the private board (once published; instructors: always)")

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

    grades = command(
        "grades", "instructors: the grades as CSV (an assignment's or the course's); students: your grade",
        run_grades,
        "Instructors: an assignment's grades on its private tracks, as CSV on standard output: generic\n"
        "(every column), or the file Canvas's or Moodle's gradebook imports (see the server README,\n"
        "Grades); without ASSIGNMENT, the course's: a column for each assignment with a rubric.\n"
        "  league grades \"Time trial\" --set-rubric rubric.json     (set how it is graded)\n"
        "  league grades \"Time trial\" --format canvas --check      (how Canvas will match the students)\n"
        "  league grades \"Time trial\" --format canvas > canvas.csv\n"
        "  league grades --format moodle --identifier idnumber > moodle.csv\n"
        "Students: league grades ASSIGNMENT prints your grade once the assignment is published.")
    grades.add_argument("assignment", nargs="?", metavar="ASSIGNMENT", help="its name or id (default: the course)")
    grades.add_argument("--format", choices=["generic", "canvas", "moodle"], default="generic",
                        help="the CSV's layout (default generic)")
    grades.add_argument("--identifier", choices=["email", "idnumber"], default="email",
                        help="moodle: the column Moodle matches students by (default email)")
    grades.add_argument("--set-rubric", metavar="FILE",
                        help="set the assignment's rubric from a JSON file ('-': standard input) and say what changed")
    grades.add_argument("--check", action="store_true",
                        help="with --format canvas: say how many rows carry an id Canvas matches, instead of the file")

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
                         help="points by finishing position in a heat (default 25,18,15,12,10,8,6,4,2,1)")
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
    jobs.add_argument("--status", choices=["queued", "running", "done", "failed"], help="only jobs of this status")
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

    race = command("race-server", "race submissions on the server (a friendly race) and print the classification",
                   run_race_server)
    race.add_argument("ids", type=int, nargs="+", metavar="SUB_ID", help="submission ids (yours first)")
    race.add_argument("--seed", type=int, help="the track's seed (default: drawn by the server)")
    race.add_argument("--replay", metavar="FILE", help="save the race's replay (JSON) for `league replay`")
    race.add_argument("--timeout", type=float, default=600, help="seconds to wait for the race (default 600)")

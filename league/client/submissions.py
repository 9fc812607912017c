"""`league submit` (check, upload, and with --wait follow the validation and evaluation) and
`league submissions` (the user's submissions and their results).

The submission statuses the client knows are TERMINAL and STAGES, here and nowhere else in it.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from league.client.api import Api, ClientError, connection, poll_delays
from league.client.check import check_files, check_limits, check_report
from league.client.output import print_table
from league.exit_codes import EXIT_ERROR, EXIT_OK, EXIT_REJECTED, EXIT_TIMEOUT
from league.statuses import DONE, ENDED, PENDING, QUEUED, READY, RUNNING, VALIDATED, VALIDATING

if TYPE_CHECKING:
    from league.validation.files import Upload

TERMINAL = set(VALIDATED)  # a submission whose validation is over
STAGES = [PENDING, VALIDATING, READY, f"evaluation {QUEUED}", f"evaluation {RUNNING}", DONE]
EPISODE_PAGE = 1000  # the most the server gives in one page
LATE_NOTE = "; late (after your due time): the late penalty applies if it is your final"


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
        if evaluation and evaluation["status"] == DONE:  # the status answer links to its episodes
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
    if submission["status"] != READY:
        return submission["status"]
    done = DONE if evaluation.get("status") == DONE else f"evaluation {evaluation.get('status', QUEUED)}"
    return f"{done} (stale: other settings)" if evaluation.get("stale") else done


def settled(submission: dict) -> bool:
    evaluation = submission.get("evaluation") or {}
    return submission["status"] in TERMINAL and (submission["status"] != READY
                                                 or evaluation.get("status") in ENDED)


def wait_settled(api: Api, submission_id: int, timeout: float, progress: bool = True) -> dict:
    """Poll the submission until validated and evaluated, with a bar of its stages (it counts
    stages, not episodes: the server tells an evaluation's figures when it is done)."""
    from tqdm import tqdm

    deadline, delays = time.monotonic() + timeout, poll_delays()
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
            time.sleep(next(delays))


def report_submission(submission: dict, as_json: bool) -> int:
    from league.evaluation import MetricsResult

    evaluation = submission.get("evaluation")
    if as_json:
        print(json.dumps(submission, indent=2))
    elif submission["status"] != READY:
        print(f"submission {submission['id']} was {submission['status']}: {submission['error']}")
    elif evaluation["status"] != DONE:
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
    ok = submission["status"] == READY and evaluation and evaluation["status"] == DONE
    return EXIT_OK if ok else EXIT_REJECTED


def run_submissions(args: argparse.Namespace) -> int:
    with Api(connection(args)) as api:
        rows = api.get("/api/submissions")
    table = [[s["id"], s["name"], stage(s), "late" if s["late"] else "", *_figures(s.get("evaluation")),
              s["error"] or ""] for s in rows]
    print_table(["id", "agent", "status", "late", "completed", "mean return", "mean speed", "error"], table, args.csv)
    return EXIT_OK


def _figures(evaluation: dict | None) -> list:
    if not evaluation or evaluation["status"] != DONE:
        return ["", "", ""]
    return [f"{evaluation['completed']}/{evaluation['episodes_total']}", f"{evaluation['mean_return']:.3f}",
            f"{evaluation['mean_speed']:.3f}"]


def add_commands(command) -> None:
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

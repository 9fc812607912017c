"""`league check`: the server's own validation (league.validation: the static checks, the checked
load and dry run, the timed calls, each within the server's CPU budgets) run on this machine,
against the configured server's limits, else (no server, or one that cannot be reached) the
league's defaults. `league submit` checks its file here first. Never imports league.server.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from league.client.api import Api, ClientError, connection
from league.exit_codes import EXIT_ERROR, EXIT_OK, EXIT_REJECTED, EXIT_UNREACHABLE

if TYPE_CHECKING:
    from league.validation.files import Upload
    from league.validation.limits import SandboxLimits
    from league.validation.report import ValidationReport


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


def add_commands(command) -> None:
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

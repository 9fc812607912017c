"""The server's log lines: one format for the API, uvicorn and the workers, with timestamps.

`log_format = text`: "2026-11-25T19:30:01.123+00:00 INFO league.server.jobs: job 12 (evaluate) done ...";
`json`: one object a line, {"at", "level", "logger", "message"} and the line's fields (`extra=`):
job lines carry job_id, kind, submission_id, race_id, user_id, outcome, duration_s; a refused upload
user_id, reason, size; each answer of the API one access line (`log_access`, from the metrics' answer
timer: method, path, status, duration_ms, user_id, client). Nothing logs a token: accounts are named
by id, and the access lines hold no query string and no header (tokens travel in the Authorization
header).

`log_file`: the lines go to that file, rotated by size (the standard library's RotatingFileHandler);
one process writes each file, so `league serve`'s worker writes its own (`worker_log_file`).
"""
from __future__ import annotations

import json
import logging
import logging.config
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

TEXT_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
# what every LogRecord has: the rest of its attributes are the line's fields (logging's `extra=`)
RECORD_ATTRIBUTES = set(vars(logging.makeLogRecord({}))) | {"message", "asctime", "color_message"}
job_log = logging.getLogger("league.server.jobs")
access_log = logging.getLogger("league.server.access")
upload_log = logging.getLogger("league.server.uploads")


class TextFormatter(logging.Formatter):
    """TEXT_FORMAT with ISO 8601 times in UTC, to the millisecond."""

    def __init__(self) -> None:
        super().__init__(TEXT_FORMAT)

    def formatTime(self, record: logging.LogRecord, datefmt: str | None = None) -> str:
        return iso_time(record.created)


class JsonFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        line = {"at": iso_time(record.created), "level": record.levelname, "logger": record.name,
                "message": record.getMessage()}
        line.update({key: value for key, value in vars(record).items() if key not in RECORD_ATTRIBUTES})
        if record.exc_info:
            line["exception"] = self.formatException(record.exc_info)
        return json.dumps(line, default=str)


def iso_time(created: float) -> str:
    return datetime.fromtimestamp(created, timezone.utc).isoformat(timespec="milliseconds")


def log_config(log_format: str, level: str, log_file: Path | None = None, max_bytes: int = 0,
               backups: int = 0) -> dict[str, Any]:
    """A logging.config dict for the root logger and uvicorn's (uvicorn's `log_config`), one format, on
    stderr or in a rotated file. uvicorn's own access lines are left out: `log_access` writes richer ones."""
    formatter = {"()": JsonFormatter if log_format == "json" else TextFormatter}
    handler = {"class": "logging.StreamHandler", "formatter": "league", "stream": "ext://sys.stderr"}
    if log_file is not None:
        handler = {"class": "logging.handlers.RotatingFileHandler", "formatter": "league", "filename": str(log_file),
                   "maxBytes": max_bytes, "backupCount": backups, "encoding": "utf-8"}
    uvicorn = {"handlers": ["default"], "level": level.upper(), "propagate": False}
    return {"version": 1, "disable_existing_loggers": False, "formatters": {"league": formatter},
            "handlers": {"default": handler},
            "loggers": {"uvicorn": uvicorn, "uvicorn.error": {"level": level.upper()},
                        "uvicorn.access": {**uvicorn, "level": "CRITICAL"}},
            "root": {"handlers": ["default"], "level": level.upper()}}


def settings_log_config(settings) -> dict[str, Any]:
    return log_config(settings.log_format, settings.log_level, settings.log_file,
                      int(settings.log_file_max_mb * 1024 * 1024), settings.log_file_backups)


def configure(settings) -> dict[str, Any]:
    """Log as the settings say (log_format, log_level, log_file); returns the config, for uvicorn."""
    if settings.log_file is not None:
        settings.log_file.parent.mkdir(parents=True, exist_ok=True)
    config = settings_log_config(settings)
    logging.config.dictConfig(config)
    return config


def worker_log_file(log_file: Path) -> Path:
    """Where `league serve`'s worker writes when the API writes `log_file`: api.log -> api-worker.log."""
    return log_file.with_name(f"{log_file.stem}-worker{log_file.suffix}")


def log_access(scope, status: int, seconds: float) -> None:
    """One answer's access line: its latency, status and user (the id the token's dependency left in the
    request's state; none for a visitor), never the query string or a header."""
    if not access_log.isEnabledFor(logging.INFO):
        return
    user_id = scope.get("state", {}).get("user_id")
    client = scope.get("client")
    fields = {"method": scope["method"], "path": scope["path"][:300], "status": status,
              "duration_ms": round(seconds * 1000, 2), "user_id": user_id, "client": client[0] if client else None}
    access_log.info("%s %s %s %.1f ms user %s client %s", fields["method"], fields["path"], status,
                    fields["duration_ms"], user_id if user_id is not None else "-", fields["client"] or "-",
                    extra=fields)


def job_outcome(outcome: Any) -> str:
    """A job's result in one word: ok or rejected (a validation), done or failed (an evaluation, a race)."""
    if hasattr(outcome, "ok"):
        return "ok" if outcome.ok else "rejected"
    return "failed" if getattr(outcome, "error", None) else "done"


def log_job(job, outcome: str, started: float, reason: str | None = None) -> None:
    """The line of a job's end: what it was for, whose, how it ended and how long it took."""
    fields = {"job_id": job.id, "kind": job.kind, "submission_id": job.submission_id, "race_id": job.race_id,
              "user_id": job.owner_id, "outcome": outcome, "duration_s": round(time.monotonic() - started, 3)}
    if reason:
        fields["reason"] = reason[:500]
    what = f"submission {job.submission_id}" if job.submission_id else f"race {job.race_id}"
    job_log.info("job %s (%s of %s, user %s) %s in %.1f s%s", job.id, job.kind, what, job.owner_id, outcome,
                 fields["duration_s"], f": {fields['reason']}" if reason else "", extra=fields)


def log_refused_upload(user_id: int, reason: str, size: int | None) -> None:
    upload_log.info("upload by user %s refused: %s (%s bytes)", user_id, reason, size if size is not None else "?",
                    extra={"user_id": user_id, "reason": reason, "size": size})

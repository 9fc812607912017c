"""Log lines (league/server/core/logs.py): the text format and the logging configuration. What the server
and its worker write, as JSON lines, is checked on a running league in tests/system/test_logs.py."""
from __future__ import annotations

import json
import logging
import logging.config

from league.server.core.logs import TextFormatter, log_config, worker_log_file


def test_text_lines_carry_a_utc_timestamp():
    record = logging.makeLogRecord({"name": "league.server", "levelname": "INFO", "msg": "hello", "created": 0.5})
    assert TextFormatter().format(record) == "1970-01-01T00:00:00.500+00:00 INFO league.server: hello"
    config = log_config("text", "warning")
    assert config["loggers"]["uvicorn"]["level"] == config["root"]["level"] == "WARNING"
    assert config["loggers"]["uvicorn.access"]["level"] == "CRITICAL"  # league.server.access says more


def test_a_log_file_is_rotated_at_its_size_and_keeps_its_backups(tmp_path):
    """The standard library's RotatingFileHandler as the settings configure it: the file never grows past
    its size, the oldest backups are deleted, every line kept is whole JSON."""
    log_file = tmp_path / "league.log"
    logging.config.dictConfig(log_config("json", "info", log_file, max_bytes=2000, backups=2))
    try:
        for number in range(200):
            logging.getLogger("league.server.test").info("line %d", number, extra={"number": number})
    finally:
        logging.config.dictConfig(log_config("text", "info"))  # back to stderr, the file closed
    kept = sorted(tmp_path.iterdir())
    assert [path.name for path in kept] == ["league.log", "league.log.1", "league.log.2"]
    assert all(path.stat().st_size <= 2000 for path in kept)
    numbers = [json.loads(line)["number"] for path in reversed(kept) for line in path.read_text().splitlines()]
    assert numbers == list(range(numbers[0], 200))  # the newest lines, in order, none lost in between


def test_serves_worker_writes_its_own_file_beside_the_apis():
    from pathlib import Path

    assert worker_log_file(Path("/var/log/league/api.log")) == Path("/var/log/league/api-worker.log")

"""Log lines (league/server/logs.py): the text format and the logging configuration. What the server
and its worker write, as JSON lines, is checked on a running league in tests/system/test_logs.py."""
from __future__ import annotations

import logging

from league.server.logs import TextFormatter, log_config


def test_text_lines_carry_a_utc_timestamp():
    record = logging.makeLogRecord({"name": "league.server", "levelname": "INFO", "msg": "hello", "created": 0.5})
    assert TextFormatter().format(record) == "1970-01-01T00:00:00.500+00:00 INFO league.server: hello"
    config = log_config("text", "warning")
    assert config["loggers"]["uvicorn.access"]["level"] == config["root"]["level"] == "WARNING"

"""`league serve`'s worker: a `league worker` child process, restarted when it dies.

The child gets SIGTERM (hands its jobs back, stops its sandboxes) when serve stops, and also if serve
dies (PR_SET_PDEATHSIG, which follows the *thread* that started it: the supervising thread, which
lives as long as the supervision); in a session of its own, so a Ctrl-C reaches only serve, which
stops it at once instead of waiting for its jobs. When it dies otherwise (killed, crashed, out of
memory) the death is logged and a new one starts after a back-off that doubles with each death in
a row (RESTART_DELAYS_S) and starts over once a child has run STABLE_S; `restarts` counts them
(league_worker_restarts_total at /metrics).
"""
from __future__ import annotations

import ctypes
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from league.server.core.logs import worker_log_file

log = logging.getLogger("league.server")
PR_SET_PDEATHSIG = 1  # prctl(2)
RESTART_DELAYS_S = (1, 2, 4, 8, 15, 30)  # the n-th death in a row waits the n-th (then the last)
STABLE_S = 60  # a child that ran this long had recovered: the next death waits the first delay again


class ChildWorker:
    def __init__(self, threads: int | None, data_dir: Path | None = None, log_file: Path | None = None):
        # the API writes log_file: the worker writes its own beside it (one writer per rotated file)
        self.env = None if log_file is None else {**os.environ, "LEAGUE_LOG_FILE": str(worker_log_file(log_file))}
        self.command = [sys.executable, "-m", "league.server", "worker",
                        *(["--threads", str(threads)] if threads else []),
                        *(["--data-dir", str(data_dir)] if data_dir else [])]
        self.restarts = 0
        self.process: subprocess.Popen | None = None
        self._stopping = threading.Event()
        self._started = threading.Event()
        self._thread = threading.Thread(target=self._supervise, name="league-serve-worker", daemon=True)

    def start(self) -> None:
        self._thread.start()
        self._started.wait()

    def stop(self, timeout_s: float = 30) -> None:
        """Stop the child (SIGTERM: it hands its jobs back), killing it after `timeout_s`."""
        self._stopping.set()
        process = self.process
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                log.warning("serve: worker process %d did not stop in %g s: killed", process.pid, timeout_s)
                process.kill()
                process.wait()
        self._thread.join(timeout_s)

    def _supervise(self) -> None:
        deaths_in_a_row = 0
        while not self._stopping.is_set():
            started = time.monotonic()
            self.process = self._spawn()
            self._started.set()
            status = self.process.wait()
            if self._stopping.is_set():
                return
            deaths_in_a_row = 1 if time.monotonic() - started >= STABLE_S else deaths_in_a_row + 1
            delay = RESTART_DELAYS_S[min(deaths_in_a_row, len(RESTART_DELAYS_S)) - 1]
            log.error("serve: worker process %d %s after %.0f s: restarting it in %g s", self.process.pid,
                      describe_exit(status), time.monotonic() - started, delay)
            if self._stopping.wait(delay):
                return
            self.restarts += 1

    def _spawn(self) -> subprocess.Popen:
        prctl, parent = ctypes.CDLL(None, use_errno=True).prctl, os.getpid()  # resolved before the fork

        def die_with_parent() -> None:
            prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
            if os.getppid() != parent:  # we died before prctl
                os.kill(os.getpid(), signal.SIGTERM)

        process = subprocess.Popen(self.command, preexec_fn=die_with_parent, start_new_session=True, env=self.env)
        log.info("serve: worker process %d started%s", process.pid,
                 f" (restart {self.restarts})" if self.restarts else "")
        return process


def describe_exit(status: int) -> str:
    """"was killed by SIGKILL", "exited with status 3" (Popen's returncode)."""
    if status < 0:
        try:
            return f"was killed by {signal.Signals(-status).name}"
        except ValueError:
            return f"was killed by signal {-status}"
    return f"exited with status {status}"

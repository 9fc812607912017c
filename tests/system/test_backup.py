"""`league backup` while the server works, `league restore` into a fresh data directory or database of
the other backend, and every answer of the restored league compared with the original's."""
from __future__ import annotations

import os
import signal
import sqlite3
import stat
import threading
import time
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from league.server.backup import BackupError, backup, backup_revision, holds_league, restore
from league.server.db.session import head_revision, make_engine, revision_of, upgrade

from ..server.api_calls import upload, wait_for
from ..server.backends import fresh_backend
from .semester import collect, differences, drained, semester
from .servers import LeagueServer, freeze, make_server

LOAD_UPLOADS = 9  # arriving while the backup is taken


def differs_by_nature(key: str) -> bool:
    """What differs between two servers that ran the same jobs at other times: when things happened,
    the ids of evaluations (and links naming them), created in the order validations happened to end,
    and sandbox logs, which name the sandbox's user id (from its pid)."""
    return key.endswith("_at") or key in ("evaluation_id", "links", "log")


def evaluation_ids_off(answer):
    if isinstance(answer, dict):
        return {k: evaluation_ids_off(v) for k, v in answer.items() if not (k == "id" and "settings" in answer)}
    if isinstance(answer, list):
        return [evaluation_ids_off(item) for item in answer]
    return answer


class Uploads(threading.Thread):
    """Students uploading one file after another (each answered before the next), as a deadline's."""

    def __init__(self, server: LeagueServer, tokens: list[str], models: dict[str, Path]):
        super().__init__(daemon=True)
        self.server, self.tokens, self.models = server, tokens, models
        self.done: list[tuple[int, str, Path, str]] = []  # (submission id, token, file, name), in order
        self.started_three = threading.Event()

    def run(self) -> None:
        files = [self.models["onnx"], self.models["torchscript"], self.models["wrong_input"]]
        for k in range(LOAD_UPLOADS):
            token, file, name = self.tokens[k % len(self.tokens)], files[k % len(files)], f"rush{k}"
            with self.server.client(token) as student:
                response = upload(student, file, name)
            assert response.status_code == 201, response.text
            self.done.append((response.json()["id"], token, file, name))
            if len(self.done) == 3:
                self.started_three.set()
            time.sleep(0.3)


def jobs_waiting_in(backup_file: Path) -> int:
    with sqlite3.connect(f"file:{backup_file}?mode=ro", uri=True) as connection:
        return connection.execute("SELECT count(*) FROM jobs WHERE status IN ('queued', 'running')").fetchone()[0]


def freeze_outside_a_write(worker, database_url: str) -> None:
    """Stop the worker (as one busy with a long job) so that jobs are certainly waiting when the
    snapshot is taken, whatever the machine's speed; never while it holds SQLite's write lock, which
    would hold the uploads too (on PostgreSQL an upload and a worker write no common row)."""
    while True:
        freeze(worker.pid)
        if not database_url.startswith("sqlite"):
            return
        probe = sqlite3.connect(database_url.removeprefix("sqlite:///"), timeout=0, isolation_level=None)
        try:
            probe.execute("BEGIN IMMEDIATE")  # fails at once if the frozen worker is inside a write
            probe.execute("ROLLBACK")
            return
        except sqlite3.OperationalError:
            worker.send_signal(signal.SIGCONT)
            time.sleep(0.05)
        finally:
            probe.close()


def restored_server(tmp_path: Path, database_url: str, original: LeagueServer) -> LeagueServer:
    """A server of the other backend on a fresh data directory, its database still empty."""
    data_dir = tmp_path / "data"
    data_dir.mkdir()
    env = {**original.env, "LEAGUE_DATA_DIR": str(data_dir), "LEAGUE_DATABASE_URL": database_url,
           "LEAGUE_CPU_SLOTS_DIR": str(tmp_path / "cpu-slots")}
    return LeagueServer(env, data_dir, instructor_token=original.instructor_token)


@pytest.mark.parametrize("source, target", [("sqlite", "postgres"), ("postgres", "sqlite")])
def test_a_backup_taken_under_load_restores_every_answer(source, target, tmp_path, models):
    (tmp_path / "original").mkdir()
    (tmp_path / "restored").mkdir()
    with fresh_backend(source, tmp_path / "original") as source_url, \
            fresh_backend(target, tmp_path / "restored") as target_url:
        original = make_server(tmp_path / "original", source_url, LEAGUE_QUOTA_PER_DAY="20")
        restored = restored_server(tmp_path / "restored", target_url, original)
        original.start_api(embedded_worker=False)
        worker = original.start_worker()
        try:
            tokens = semester(original, models)
            load = Uploads(original, tokens, models)
            load.start()
            assert load.started_three.wait(60)
            freeze_outside_a_write(worker, source_url)
            wait_for(lambda: len(load.done), lambda n: n > 3, timeout=60)  # one upload since: its job waits
            backup_file = tmp_path / "backups" / "league.bak"
            backup_file.parent.mkdir()
            acknowledged = {submission_id for submission_id, *_ in load.done}
            umask = os.umask(0o022)  # a shell's: the backup must not be readable by others all the same
            try:
                taken = original.command("backup", str(backup_file))
            finally:
                os.umask(umask)
                worker.send_signal(signal.SIGCONT)
            load.join(120)
            assert taken.returncode == 0, taken.stderr
            assert stat.S_IMODE(backup_file.stat().st_mode) == 0o600
            assert [p.name for p in backup_file.parent.iterdir()] == ["league.bak"]  # no temporary file left
            assert jobs_waiting_in(backup_file) > 0  # it was taken while jobs were queued or running

            put_back = restored.command("restore", str(backup_file))
            assert put_back.returncode == 0, put_back.stderr
            restored.start_api()
            drained(restored, timeout=90)  # the jobs queued and running at the backup, at once (no message needed)
            _replay_the_uploads_after_the_backup(original, restored, load.done, acknowledged)
            drained(original)
            drained(restored)
            ours = collect(original.url, original.instructor_token, tokens)
            theirs = collect(restored.url, restored.instructor_token, tokens)
        finally:
            original.stop_all()
            restored.stop_all()
    assert ours.keys() == theirs.keys()
    before_the_load = {"/api/races", "/api/championships"} | {
        path for path in ours if path.startswith(("/api/races/", "/api/championships/"))}
    for path in before_the_load:  # finished before the backup: the same, to the microsecond
        assert differences(ours[path], theirs[path], path) == []
    for path in ours:  # the whole league once both ran the same jobs (the restored one later)
        assert differences(evaluation_ids_off(ours[path]), evaluation_ids_off(theirs[path]), path,
                           ignore=differs_by_nature) == []
    if target == "sqlite":
        assert stat.S_IMODE((tmp_path / "restored" / "league.db").stat().st_mode) == 0o600


def _replay_the_uploads_after_the_backup(original: LeagueServer, restored: LeagueServer,
                                         uploads: list[tuple[int, str, Path, str]], acknowledged: set[int]) -> None:
    """Upload to the restored league what reached the original after the backup's snapshot, in the same
    order: both then hold the same submissions, under the same ids."""
    with restored.client(restored.instructor_token) as instructor:
        present = {s["id"] for s in instructor.get("/api/submissions", params={"all": True}).json()}
    assert acknowledged <= present  # every upload answered before the backup began is in it
    for submission_id, token, file, name in uploads:
        if submission_id not in present:
            with restored.client(token) as student:
                response = upload(student, file, name)
            assert response.status_code == 201, response.text
            assert response.json()["id"] == submission_id


# --------------------------------------------------------------------------- restore's rules, in process


def league_with_a_user(url: str, revision: str = "head") -> None:
    """A league at `revision` holding a course and a student, written with SQL (as that revision's code would;
    head's: written at 0008, then migrated, which gives the course its default assignment)."""
    engine = create_engine(url)
    with engine.connect() as connection:
        upgrade(connection, "0008" if revision == "head" else revision)
    with engine.begin() as connection:
        connection.execute(text("INSERT INTO courses (id, name, eval_seed, eval_episodes, eval_env_options, created_at,"
                                " updated_at) VALUES (1, 'default', 0, 3, '{}', '2026-01-05', '2026-01-05')"))
        connection.execute(text("INSERT INTO users (id, name, role, course_id, token_hash, created_at) VALUES "
                                "(1, 'ann', 'student', 1, :hash, '2026-01-05 10:00:00')"), {"hash": "ab" * 32})
    if revision == "head":
        with engine.connect() as connection:
            upgrade(connection, revision)
    engine.dispose()


def users_of(url: str) -> list[tuple]:
    engine = create_engine(url)
    try:
        with engine.connect() as connection:
            return [tuple(row) for row in connection.execute(text("SELECT id, name, token_hash FROM users"))]
    finally:
        engine.dispose()


@pytest.mark.parametrize("source, target", [("sqlite", "postgres"), ("postgres", "sqlite")])
def test_an_older_backup_is_restored_at_this_schema_into_an_empty_database_only(source, target, tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with fresh_backend(source, tmp_path / "a") as source_url, \
            fresh_backend(target, tmp_path / "b") as target_url:
        league_with_a_user(source_url, "0005")  # an older release's league
        engine = make_engine(source_url)
        with engine.connect() as connection:
            report = backup(engine, revision_of(connection), tmp_path / "old.bak")
        engine.dispose()
        assert (report.revision, report.counts["users"]) == ("0005", 1)
        assert backup_revision(tmp_path / "old.bak") == "0005"

        restore(tmp_path / "old.bak", target_url)
        engine = make_engine(target_url)
        with engine.connect() as connection:
            assert revision_of(connection) == head_revision()
        engine.dispose()
        assert users_of(target_url) == [(1, "ann", "ab" * 32)]
        with pytest.raises(BackupError, match="already holds a league: restore into a fresh data directory or an "
                                              "empty database, or give --replace to overwrite it"):
            restore(tmp_path / "old.bak", target_url)
        league_with_a_user(f"sqlite:///{tmp_path / 'other.db'}")
        restore(tmp_path / "other.db", target_url, replace=True)  # a league's database is a backup too
        assert users_of(target_url) == [(1, "ann", "ab" * 32)]
        assert holds_league(target_url)


def test_what_is_no_backup_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("not a database")
    with pytest.raises(BackupError, match=r"notes.txt is not a league backup \(written by `league backup`\)"):
        backup_revision(tmp_path / "notes.txt")
    with pytest.raises(BackupError, match="no such backup file"):
        backup_revision(tmp_path / "missing.bak")
    newer = tmp_path / "newer.bak"
    league_with_a_user(f"sqlite:///{newer}")
    with sqlite3.connect(newer) as connection:
        connection.execute("UPDATE alembic_version SET version_num = '0999'")
    with pytest.raises(BackupError, match="newer.bak: this database is at revision 0999, written by a newer version "
                                          "of microracer-league"):
        backup_revision(newer)

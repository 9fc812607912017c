"""The integrity report over real HTTP, on SQLite and on PostgreSQL: real
uploads validated (and probed) in real sandboxes, in a course of the test's own."""
from __future__ import annotations

import csv
import io
import os
import subprocess
import sys

from sqlalchemy import update

from league.agents import export_onnx, export_torchscript
from league.server.config import BUNDLED_BASELINES
from league.server.db.models import Submission
from league.server.db.session import make_engine, make_sessionmaker
from league.server.integrity import CSV_COLUMNS
from league.testing import thesis_driver

from ...server.api_calls import submission, unique, upload, wait_for
from ..servers import add_user_in_new_course


def upload_all(uploads: dict[str, tuple]) -> dict[str, int]:
    """Upload every (client, file) at once, then wait until each is validated (the report needs no
    evaluation); the submissions' ids."""
    sent = {}
    for key, (client, path) in uploads.items():
        response = upload(client, path)
        assert response.status_code == 201, response.text
        sent[key] = response.json()["id"]
    for key, (client, _) in uploads.items():
        done = wait_for(lambda: submission(client, sent[key]),  # noqa: B023 - called in this iteration
                        lambda s: s["status"] in ("ready", "rejected", "failed"), timeout=180)
        assert done["status"] == "ready", done["error"]
    return sent


def groups_by_kind(report: dict) -> dict[str, list[dict]]:
    kinds: dict[str, list[dict]] = {}
    for group in report["groups"]:
        kinds.setdefault(group["kind"], []).append(group)
    return kinds


def league_cli(server, token: str, *args: str) -> subprocess.CompletedProcess:
    """`league ARGS` in a terminal with the server and token in the environment."""
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("LEAGUE_")},
           "PYTHONPATH": server.env["PYTHONPATH"], "LEAGUE_SERVER": server.url, "LEAGUE_TOKEN": token}
    return subprocess.run([sys.executable, "-m", "league.cli", *args], env=env, capture_output=True, text=True,
                          timeout=120)


def forget_probe(server, submission_id: int) -> None:
    """The submission as one validated before probes were recorded (an upgraded server's)."""
    engine = make_engine(server.env["LEAGUE_DATABASE_URL"])
    try:
        with make_sessionmaker(engine).begin() as session:
            session.execute(update(Submission).where(Submission.id == submission_id)
                            .values(probe_key=None, probe_actions=None))
    finally:
        engine.dispose()


def test_copies_are_grouped_and_different_agents_are_not(league_server, tmp_path):
    """An identical file by two students, one network exported to ONNX and to TorchScript by two
    students, a bundled baseline re-uploaded: three groups; two other agents, alike in structure
    but not in behaviour (thesis drivers holding other speeds), are in none."""
    prof = league_server.client(add_user_in_new_course(league_server, unique("prof"), unique("course"),
                                                       role="instructor"))
    names = {key: unique(key) for key in ("ann", "bob", "cy", "dee", "eve", "fay")}
    students = {}
    for key, name in names.items():
        response = prof.post("/api/users", json={"name": name})
        assert response.status_code == 201, response.text
        students[key] = league_server.client(response.json()["token"])
    shared = export_onnx(thesis_driver(seed=1, target_speed=0.21), tmp_path / "shared.onnx")
    twice = thesis_driver(seed=2, target_speed=0.29)
    other = export_onnx(thesis_driver(seed=3, target_speed=0.37), tmp_path / "other.onnx")
    files = {"ann": shared, "bob": shared, "cy": export_onnx(twice, tmp_path / "mine.onnx"),
             "dee": export_torchscript(twice, tmp_path / "mine.pt"), "eve": BUNDLED_BASELINES / "ppo.onnx",
             "fay": other}
    ids = upload_all({key: (students[key], path) for key, path in files.items()})

    response = prof.get("/api/integrity")

    assert response.status_code == 200, response.text
    report = response.json()
    assert report["not_compared"] == [] and report["compared"] == report["submissions"] >= 7, report
    assert report["probes"] == 64 and report["tolerance"] == 1e-3
    kinds = groups_by_kind(report)
    assert sorted(kinds) == ["baseline_copy", "identical_file", "same_behaviour"], report
    [identical], [behaviour], [copy] = kinds["identical_file"], kinds["same_behaviour"], kinds["baseline_copy"]
    assert identical["students"] == sorted([names["ann"], names["bob"]])
    assert [s["id"] for s in identical["submissions"]] == [ids["ann"], ids["bob"]] and identical["distance"] == 0
    assert behaviour["students"] == sorted([names["cy"], names["dee"]])
    assert [s["kind"] for s in behaviour["submissions"]] == ["onnx", "torchscript"]
    assert 0 <= behaviour["distance"] <= 1e-3
    assert (copy["students"], copy["baseline"]) == ([names["eve"]], "ppo.onnx")
    assert [s["id"] for s in copy["submissions"]] == [ids["eve"]]
    assert not any(names["fay"] in group["students"] for group in report["groups"])

    # the CSV: the same groups, one line per submission, cells a spreadsheet reads as data
    sheet = prof.get("/api/integrity.csv")
    assert sheet.status_code == 200 and sheet.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(sheet.text)))
    assert list(rows[0]) == CSV_COLUMNS
    assert sorted((row["kind"], int(row["submission_id"])) for row in rows) == sorted(
        [(g["kind"], s["id"]) for g in report["groups"] for s in g["submissions"]])

    # the same in a terminal: one line per submission of each group
    terminal = league_cli(league_server, prof.headers["Authorization"].removeprefix("Bearer "), "integrity")
    assert terminal.returncode == 0, terminal.stderr
    lines = terminal.stdout.splitlines()
    assert lines[0].split() == ["group", "kind", "distance", "owner", "id", "agent", "file"]
    assert any("baseline_copy (ppo.onnx)" in line and names["eve"] in line for line in lines)

    # students see none of it
    for path, method in (("/api/integrity", "GET"), ("/api/integrity.csv", "GET"), ("/api/integrity/probe", "POST")):
        refused = students["ann"].request(method, path)
        assert (refused.status_code, refused.json()) == (403, {"detail": "only instructors may do this"})
    terminal = league_cli(league_server, students["ann"].headers["Authorization"].removeprefix("Bearer "), "integrity")
    assert terminal.returncode == 3 and "only instructors may do this" in terminal.stderr

    # a submission validated before probes were recorded is compared by file only, until probed
    forget_probe(league_server, ids["dee"])
    report = prof.get("/api/integrity").json()
    assert [(s["id"], s["reason"]) for s in report["not_compared"]] == [(ids["dee"], "not yet probed")]
    assert "same_behaviour" not in groups_by_kind(report)
    queued = prof.post("/api/integrity/probe")
    assert queued.status_code == 200 and queued.json() == {"queued": [ids["dee"]]}
    assert prof.post("/api/integrity/probe").json() == {"queued": []}  # waiting or done: not queued twice
    [event] = [e for e in prof.get("/api/audit").json()["items"] if e["action"] == "integrity.probe"]
    assert (event["target_kind"], event["details"]) == ("course", {"queued": 1})  # the empty one is not recorded
    report = wait_for(lambda: prof.get("/api/integrity").json(), lambda r: not r["not_compared"], timeout=120)
    [behaviour] = groups_by_kind(report)["same_behaviour"]
    assert [s["id"] for s in behaviour["submissions"]] == [ids["cy"], ids["dee"]]

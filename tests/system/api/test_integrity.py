"""The integrity report over real HTTP, on SQLite and on PostgreSQL: real
uploads validated (and probed) in real sandboxes, in a course of the test's own."""
from __future__ import annotations

import csv
import io
import os
import subprocess
import sys

from sqlalchemy import delete, update

from league.agents import export_onnx, export_torchscript
from league.server.core.config import BUNDLED_BASELINES, Settings
from league.server.course.integrity import CSV_COLUMNS
from league.server.db.models import Submission, SubmissionProbe
from league.server.db.session import make_engine, make_sessionmaker
from league.testing import onnx_probe_aware, onnx_scaled_last_layer, thesis_driver
from league.validation.probes import probe_observations

from ...server.api_calls import submission, unique, upload, wait_for
from ..servers import add_user_in_new_course, wait_for_the_baselines


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


def own_submission(student, submission_id: int) -> dict:
    """What a student reads of their submission (its log included), but its evaluation, which runs meanwhile."""
    answer = student.get(f"/api/submissions/{submission_id}").json()
    return {key: value for key, value in answer.items() if key not in ("evaluation", "links")}


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
    """The submission as one validated before probes were recorded (an upgraded server's): no
    actions on the public set nor on a secret one."""
    engine = make_engine(server.env["LEAGUE_DATABASE_URL"])
    try:
        with make_sessionmaker(engine).begin() as session:
            session.execute(update(Submission).where(Submission.id == submission_id)
                            .values(probe_key=None, probe_actions=None))
            session.execute(delete(SubmissionProbe).where(SubmissionProbe.submission_id == submission_id))
    finally:
        engine.dispose()


def test_copies_are_grouped_and_different_agents_are_not(league_server, tmp_path):
    """An identical file by two students, one network exported to ONNX and to TorchScript by two
    students, a bundled baseline re-uploaded, rescaled (last layer x 1.03) and made probe-aware (it
    answers the public probe set otherwise): three groups once the secret set is probed; two other
    agents, alike in structure but not in behaviour (thesis drivers holding other speeds), are in none."""
    wait_for_the_baselines(league_server)  # ready, so that they are probed with the students
    prof = league_server.client(add_user_in_new_course(league_server, unique("prof"), unique("course"),
                                                       role="instructor"))
    names = {key: unique(key) for key in ("ann", "bob", "cy", "dee", "eve", "fay", "gus", "hal")}
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
             "fay": other, "gus": onnx_scaled_last_layer(BUNDLED_BASELINES / "ppo.onnx", tmp_path / "gus.onnx"),
             "hal": onnx_probe_aware(BUNDLED_BASELINES / "ppo.onnx", tmp_path / "hal.onnx", probe_observations(20))}
    ids = upload_all({key: (students[key], path) for key, path in files.items()})

    # on the public set alone, the probe-aware copy is apart; the secret set is probed on request only
    report = prof.get("/api/integrity").json()
    assert {s["id"] for s in report["not_compared"]} >= set(ids.values()), report
    assert {s["reason"] for s in report["not_compared"]} == {"not yet probed"}
    assert not any(names["hal"] in group["students"] for group in report["groups"])
    seen_by_hal = own_submission(students["hal"], ids["hal"])
    queued = prof.post("/api/integrity/probe")
    assert queued.status_code == 200 and set(ids.values()) <= set(queued.json()["queued"]), queued.text
    queued_first = queued.json()["queued"]
    secret_jobs = [j for j in prof.get("/api/jobs").json() if j["kind"] == "secret_probe"]
    assert {j["submission_id"] for j in secret_jobs} == set(queued.json()["queued"])
    report = wait_for(lambda: prof.get("/api/integrity").json(), lambda r: not r["not_compared"], timeout=180)
    # nothing of it reaches the student: their submission reads as before, the jobs are the instructor's
    assert own_submission(students["hal"], ids["hal"]) == seen_by_hal
    assert students["hal"].get("/api/jobs").status_code == 403

    response = prof.get("/api/integrity")

    assert response.status_code == 200, response.text
    report = response.json()
    assert report["not_compared"] == [] and report["compared"] == report["submissions"] >= 9, report
    assert report["probes"] == 64 and report["tolerance"] == Settings().integrity_tolerance
    kinds = groups_by_kind(report)
    assert sorted(kinds) == ["baseline_copy", "identical_file", "same_behaviour"], report
    [identical], [behaviour], [copy] = kinds["identical_file"], kinds["same_behaviour"], kinds["baseline_copy"]
    assert identical["students"] == sorted([names["ann"], names["bob"]])
    assert [s["id"] for s in identical["submissions"]] == [ids["ann"], ids["bob"]] and identical["distance"] == 0
    assert behaviour["students"] == sorted([names["cy"], names["dee"]])
    assert [s["kind"] for s in behaviour["submissions"]] == ["onnx", "torchscript"]
    assert 0 <= behaviour["distance"] <= 1e-3
    assert (copy["students"], copy["baseline"]) == (sorted(names[k] for k in ("eve", "gus", "hal")), "ppo.onnx")
    assert [s["id"] for s in copy["submissions"]] == [ids["eve"], ids["gus"], ids["hal"]]
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
    events = [e for e in prof.get("/api/audit").json()["items"] if e["action"] == "integrity.probe"]
    assert [(e["target_kind"], e["details"]) for e in events] == [  # newest first; the empty one is not recorded
        ("course", {"queued": 1}), ("course", {"queued": len(queued_first)})]
    report = wait_for(lambda: prof.get("/api/integrity").json(), lambda r: not r["not_compared"], timeout=120)
    [behaviour] = groups_by_kind(report)["same_behaviour"]
    assert [s["id"] for s in behaviour["submissions"]] == [ids["cy"], ids["dee"]]

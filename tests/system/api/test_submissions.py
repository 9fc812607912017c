"""Submissions on a running league (a `league serve` and its worker, on SQLite and on PostgreSQL):
what only a worker can show -- an upload validated and evaluated to the figures of `league evaluate`,
each hostile file rejected with its reason in a real sandbox, the bundled baselines registered on the
first start, a burst of uploads against the quota. The refusals: tests/server/api/routes/."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor

import pytest

from league.evaluation import league_versions

from ...server.api_calls import create_student, episodes, unique, upload, wait_settled
from ...server.backends import TEST_SETTINGS

EPISODES, SEED = int(TEST_SETTINGS["LEAGUE_EVAL_EPISODES"]), int(TEST_SETTINGS["LEAGUE_EVAL_SEED"])


@pytest.mark.parametrize("kind", ["onnx", "torchscript"])
def test_upload_becomes_ready_with_the_figures_of_league_evaluate(league_server, models, kind):
    student = create_student(league_server, unique("alice"))
    response = upload(student, models[kind], name=f"my {kind} actor")
    assert response.status_code == 201, response.text
    assert set(response.json()) == {"id", "status"} and response.json()["status"] == "pending"

    result = wait_settled(student, response.json()["id"])

    assert result["status"] == "ready", result["error"]
    assert (result["name"], result["kind"], result["obs_dim"]) == (f"my {kind} actor", kind, 5)
    evaluation = result["evaluation"]
    assert evaluation["status"] == "done", evaluation["error"]
    assert evaluation["settings"] == {"seed": SEED, "episodes": EPISODES, "env_options": {}}
    assert evaluation["stale"] is False and evaluation["versions"] == league_versions()
    # what the student gets from `league evaluate` on the same seed: the same figures, to the last bit
    cli = subprocess.run([sys.executable, "-m", "league.cli", "evaluate", str(models[kind]), "--seed", str(SEED),
                          "--episodes", str(EPISODES), "--json", "--no-progress"],
                         capture_output=True, text=True, timeout=120, check=True)
    local = json.loads(cli.stdout)
    assert "episodes" not in evaluation  # the status answer is small; they have a link
    assert result["links"]["episodes"] == \
        f"/api/submissions/{result['id']}/episodes?evaluation_id={evaluation['id']}"
    served = episodes(student, result["id"], evaluation["id"], limit=2)  # paged: two pages of 3 episodes
    assert [{k: v for k, v in e.items() if k != "index"} for e in served] == local["episodes"]
    assert evaluation["completed"] == local["completed"] and evaluation["episodes_total"] == EPISODES
    assert (evaluation["mean_return"], evaluation["mean_speed"]) == (local["mean_return"], local["mean_speed"])
    # what produced it, as the student's own run records it: compare the keys
    assert (evaluation["result_key"], evaluation["versions"]) == (local["settings"]["result_key"],
                                                                    local["settings"]["versions"])
    assert "network namespace" in evaluation["log"] or "network user-namespace" in evaluation["log"]


BAD_UPLOADS = {
    "random_bytes": r"not an ONNX model",
    "truncated": r"not an ONNX model \(or the file is truncated\)",
    "pickle_pt": r"is a Python pickle, not TorchScript",
    "wrong_input": r"wrong input size: the model takes 7 values per observation",
    "wrong_output": r"the model returns 3 values per observation, expected 2",
    "nan": r"NaN or infinite actions",
    "loop": r"did not load and pass its dry run within 8 s of CPU time",
    "slow": r"ms of CPU per observation",
    "memory_hog": r"out of memory \(the cap is 512 MB\)",
    "external_data": r"refers to external data",
    "custom_domain": r"non-standard operator domain 'com.example'",
    "reads_file": r"operator aten::from_file \(in .*forward\) is not allowed",
}


@pytest.mark.parametrize("bad", sorted(BAD_UPLOADS))
def test_bad_model_is_rejected_with_its_reason_and_the_server_goes_on(league_server, models, bad):
    student = create_student(league_server, unique(bad))
    response = upload(student, models[bad])
    assert response.status_code == 201, response.text

    result = wait_settled(student, response.json()["id"])

    assert result["status"] == "rejected"
    assert re.search(BAD_UPLOADS[bad], result["error"]), result["error"]
    assert result["evaluation"] is None
    assert isinstance(result["log"], str)
    assert student.get("/api/health").status_code == 200


def test_students_see_only_their_own_submissions(league_server, models):
    alice, bob = create_student(league_server, unique("alice")), create_student(league_server, unique("bob"))
    alice_id = upload(alice, models["heuristic_onnx"]).json()["id"]
    wait_settled(alice, alice_id)

    assert bob.get(f"/api/submissions/{alice_id}").status_code == 404
    assert bob.get("/api/submissions").json() == []
    assert [s["id"] for s in alice.get("/api/submissions").json()] == [alice_id]
    with league_server.client(league_server.instructor_token) as instructor:
        seen = instructor.get(f"/api/submissions/{alice_id}")
        assert seen.status_code == 200 and seen.json()["log"] is not None
        assert alice_id in [s["id"] for s in instructor.get("/api/submissions", params={"all": True}).json()]


def test_the_baselines_are_registered_and_evaluated_on_the_first_start(league_server):
    with league_server.client(league_server.instructor_token) as instructor:
        listing = instructor.get("/api/submissions", params={"all": True}).json()
        baselines = [s for s in listing if s["owner"] == "baselines"]
        assert [s["name"] for s in baselines] == ["heuristic"]
        settled = wait_settled(instructor, baselines[0]["id"])
    assert settled["status"] == "ready" and settled["evaluation"]["status"] == "done"
    assert (league_server.data_dir / "baselines" / "heuristic.onnx").is_file()


def test_parallel_uploads_never_pass_the_quota(league_server, models):
    """40 uploads at once (the API's thread pool is 40) against a quota of 4 (LEAGUE_QUOTA_PER_DAY):
    exactly 4 accepted, every answer in time. Each upload checks its token, then opens a session of
    its own: were the first session's connection kept, a burst would hold the whole connection pool
    and wait on itself."""
    student = create_student(league_server, unique("rush"))
    parallel = 40
    start = threading.Barrier(parallel)

    def post(_):
        with league_server.client(student.headers["Authorization"].split()[1]) as client:
            start.wait()
            return upload(client, models["heuristic_onnx"]).status_code

    with ThreadPoolExecutor(parallel) as pool:
        statuses = sorted(pool.map(post, range(parallel)))
    assert statuses == [201] * 4 + [429] * (parallel - 4)
    assert len(student.get("/api/submissions").json()) == 4

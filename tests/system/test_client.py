"""The `league` client commands against a real server (a `league serve` subprocess on SQLite):
`league check` says what the server says of every model file the server tests upload; login,
submit --wait, listings, grades and a friendly race from the terminal; bad token, quota and a
server that is down give their own message and exit code."""
from __future__ import annotations

import csv
import io
import json
import re
import stat
import subprocess
import sys

import pytest

from league.agents import load_agent
from league.exit_codes import EXIT_AUTH, EXIT_ERROR, EXIT_OK, EXIT_REFUSED, EXIT_REJECTED, EXIT_UNREACHABLE
from league.server.api.deps import UNKNOWN_TOKEN
from league.evaluation import metrics_run

from ..server.api_calls import create_student, unique, upload, wait_for, wait_settled
from ..server.backends import TEST_SETTINGS
from .servers import baseline_submission, free_port, instructor_of_a_new_course, student_token
from .students import league, student_env

EPISODES, SEED = int(TEST_SETTINGS["LEAGUE_EVAL_EPISODES"]), int(TEST_SETTINGS["LEAGUE_EVAL_SEED"])
# Too slow: the load's dry run, a call or the median may be the first to use up its CPU time
TIMED = {"slow": r"ms of CPU per observation|may use 20 ms per observation"}


@pytest.mark.long
def test_check_rejects_exactly_what_the_server_rejects(sqlite_server, models, tmp_path):
    """Every model file of the server tests, good and hostile: uploaded (one student each), and
    checked here with one `league check` of them all against the server's limits; the same verdict
    and reason, file for file, in order."""
    uploaded = {}
    for kind, path in models.items():
        response = upload(create_student(sqlite_server, unique(kind)), path)
        assert response.status_code == 201, response.text
        uploaded[kind] = response.json()["id"]
    checked = league("check", *map(str, models.values()), "--server", sqlite_server.url, config=tmp_path)
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        served = {kind: wait_settled(instructor, uploaded[kind], timeout=120) for kind in models}

    assert checked.returncode == EXIT_REJECTED, checked.stderr  # some are rejected: not every file would pass
    starts = [checked.stdout.index(f"{path.name}: the server would ") for path in models.values()]
    assert starts == sorted(starts) and starts[0] == 0, checked.stdout  # one report per file, in order
    reports = dict(zip(models, (checked.stdout[a:b] for a, b in zip(starts, [*starts[1:], None]))))
    for kind, report in reports.items():
        verdict = served[kind]
        name = models[kind].name
        if kind == "external_data":  # checked as `league submit` uploads it: packed into one file
            assert verdict["status"] == "rejected" and "external_data=False" in verdict["error"], verdict
            assert re.fullmatch(rf"{re.escape(name)}: the server would accept it: .*; its weights in weights.bin "
                                r"are packed in \(`league submit` uploads one file\)\n", report), report
        elif verdict["status"] == "ready":
            assert re.fullmatch(rf"{re.escape(name)}: the server would accept it: observation size 5, "
                                r"[\d.]+ ms of CPU per observation \(limit 20 ms\)\n", report), report
        elif kind in TIMED:
            assert re.search(TIMED[kind], verdict["error"]) and re.search(TIMED[kind], report), \
                (verdict["error"], report)
        else:
            assert report.startswith(f"{name}: the server would reject it: {verdict['error']}"), \
                (verdict["error"], report)
    assert sum(v["status"] == "ready" for v in served.values()) == 3  # the good ones: onnx, torchscript, heuristic
    good = [models[kind] for kind in models if served[kind]["status"] == "ready" or kind == "external_data"]
    all_good = league("check", *map(str, good), "--server", sqlite_server.url, config=tmp_path)
    assert all_good.returncode == EXIT_OK, all_good.stdout + all_good.stderr
    assert all_good.stdout.count("the server would accept it") == 4


def test_check_says_its_verdict_only_and_a_timing_once(models, tmp_path):
    """No server: the league's defaults, but for a budget of 1 us per observation (every model is
    over it), which the model's figures are given against, once; nothing else is said."""
    checked = league("check", str(models["heuristic_onnx"]), "--step-deadline-ms", "0.001", config=tmp_path)
    assert (checked.returncode, checked.stderr) == (EXIT_REJECTED, "")
    assert re.fullmatch(rf"{models['heuristic_onnx'].name}: the server would reject it: the model is too slow: "
                        r"it uses [\d.]+ ms of CPU per observation, the limit is 0.001 ms\n", checked.stdout)


def test_a_student_logs_in_submits_waits_and_races_from_the_terminal(sqlite_server, models, tmp_path):
    name = unique("terminal")
    token = student_token(sqlite_server, name)

    login = league("login", "--server", sqlite_server.url, "--token", token, config=tmp_path)
    assert login.returncode == EXIT_OK, login.stderr
    assert f"as {name} (student)" in login.stdout
    saved = next(tmp_path.rglob("client.json"))
    assert stat.S_IMODE(saved.stat().st_mode) == 0o600

    submitted = league("submit", str(models["onnx"]), "--name", "my actor", "--wait", config=tmp_path)
    assert submitted.returncode == EXIT_OK, submitted.stderr
    assert "the server would accept it" in submitted.stderr  # checked first
    assert re.search(r"submission \d+: done .* stage 6/6", submitted.stderr)  # the bar counts stages, and says so
    local = metrics_run(load_agent(models["onnx"]), episodes=EPISODES, seed=SEED)
    lines = submitted.stdout.splitlines()
    assert re.fullmatch(r"submission \d+ is ready", lines[0])
    assert lines[1].startswith(f"my actor: {EPISODES} episodes, seed {SEED}")
    assert lines[2:] == local.table().splitlines()[1:]  # the same figures as `league evaluate`

    listing = league("submissions", "--csv", config=tmp_path)
    assert listing.returncode == EXIT_OK, listing.stderr
    rows = list(csv.DictReader(io.StringIO(listing.stdout)))
    assert [(r["agent"], r["status"], r["completed"]) for r in rows] == [
        ("my actor", "done", f"{local.completed}/{EPISODES}")]
    piped = subprocess.Popen([sys.executable, "-m", "league", "submissions"], cwd=tmp_path, env=student_env(tmp_path),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    piped.stdout.close()  # `league submissions | head` once head has quit
    assert (piped.stderr.read(), piped.wait(timeout=120)) == ("", 141)

    baseline = baseline_submission(sqlite_server)
    raced = league("race-server", rows[0]["id"], str(baseline["id"]), "--seed", "5",
                   "--replay", str(tmp_path / "race.json"), config=tmp_path)
    assert raced.returncode == EXIT_OK, raced.stderr
    assert raced.stdout.startswith("race ") and " on seed 5\n" in raced.stdout
    assert "my actor" in raced.stdout and (tmp_path / "race.json").stat().st_size > 1000
    replayed = league("replay", str(tmp_path / "race.json"), config=tmp_path)
    assert replayed.returncode == EXIT_OK and replayed.stdout.splitlines()[1:] == raced.stdout.splitlines()[1:]


def test_instructors_get_the_grades_from_the_terminal(sqlite_server, tmp_path):
    name = unique("graded")
    student_token(sqlite_server, name)
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        cup = unique("cup")
        championship = instructor.post("/api/championships", json={"name": cup}).json()["id"]
    env = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": sqlite_server.instructor_token}
    standings = league("standings", str(championship), "--csv", config=tmp_path, **env)
    by_name = league("standings", cup.upper(), "--csv", config=tmp_path, **env)  # students know its name
    assert by_name.returncode == EXIT_OK and by_name.stdout == standings.stdout, by_name.stderr
    grades = league("leaderboard", "--csv", config=tmp_path, **env)
    assert standings.returncode == grades.returncode == EXIT_OK, (standings.stderr, grades.stderr)
    no_round = [row for row in csv.DictReader(io.StringIO(standings.stdout)) if row["student"] == name]
    assert no_round == [{**{key: "" for key in no_round[0]}, "student": name}]
    assert name in [row["student"] for row in csv.DictReader(io.StringIO(grades.stdout))]
    refused = league("standings", str(championship), "--csv", config=tmp_path, LEAGUE_SERVER=sqlite_server.url,
                     LEAGUE_TOKEN=student_token(sqlite_server, unique("nosy")))
    assert refused.returncode == EXIT_AUTH
    assert refused.stderr == "league: error: the server refused: only instructors may do this\n"


@pytest.mark.long
def test_an_assignment_is_graded_on_its_private_tracks_and_exported_from_the_terminal(sqlite_server, models, tmp_path):
    """End to end on a running server: two students upload, the due time is moved into the past, the
    server freezes their finals and its worker evaluates them on the private tracks; the instructor
    sets a rubric and exports the grades (generic, Canvas, Moodle); a student reads their own grade
    once the assignment is published."""
    from datetime import datetime, timedelta, timezone

    title, now = unique("Graded"), datetime.now(timezone.utc)
    # a course of its own: its assignment replaces the automatic one there, not in the course the other tests share
    prof = instructor_of_a_new_course(sqlite_server)
    with sqlite_server.client(prof) as instructor:
        created = instructor.post("/api/assignments", json={"name": title, "episodes": EPISODES,
                                                            "due_at": (now + timedelta(hours=1)).isoformat()})
        assert created.status_code == 201, created.text
        assignment = created.json()
        students = {}
        for who, email in (("fast", "fast@uni.example"), ("slow", None)):
            answer = instructor.post("/api/users", json={"name": unique(who), "email": email})
            students[who] = answer.json()
    for who, model in (("fast", models["onnx"]), ("slow", models["heuristic_onnx"])):
        with sqlite_server.client(students[who]["token"]) as client, open(model, "rb") as handle:
            sent = client.post("/api/submissions", files={"file": (model.name, handle)},
                               data={"name": who, "assignment": title})
            assert sent.status_code == 201, sent.text
            assert wait_settled(client, sent.json()["id"], timeout=180)["status"] == "ready"
    # the due time passes: the reaper closes it
    with sqlite_server.client(prof) as instructor:
        moved = instructor.patch(f"/api/assignments/{assignment['id']}",
                                 json={"due_at": (now - timedelta(minutes=1)).isoformat()})
        assert moved.status_code == 200, moved.text
    (tmp_path / "rubric.json").write_text(json.dumps({"kind": "formula", "max_points": 10,
                                                       "formula": "10 * completed"}))
    env = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": prof}
    set_rubric = league("grades", title, "--set-rubric", str(tmp_path / "rubric.json"), config=tmp_path, **env)
    assert set_rubric.returncode == EXIT_OK, set_rubric.stderr
    assert set_rubric.stdout == (f'{title}: rubric set to {{"kind":"formula","max_points":10.0,"formula":"10 * '
                                 f'completed"}} (was none); `league grades {title!r}` prints the grades\n')

    with sqlite_server.client(prof) as instructor:
        wait_for(lambda: instructor.get(f"/api/assignments/{assignment['id']}/grades").json()["rows"],
                 lambda rows: sum(row["status"] == "graded" for row in rows) == 2, timeout=180, interval=0.2)
    table = league("grades", title, config=tmp_path, **env)
    assert table.returncode == EXIT_OK, table.stderr
    rows = {row["name"]: row for row in csv.DictReader(io.StringIO(table.stdout)) if row["role"] == "student"}
    fast, slow = rows[students["fast"]["name"]], rows[students["slow"]["name"]]
    private_run = metrics_run(load_agent(models["onnx"]), episodes=EPISODES,
                              seed=_private_seed(sqlite_server, prof, assignment))
    assert float(fast["completed"]) == pytest.approx(private_run.completed / EPISODES, abs=1e-4)
    assert float(fast["points"]) == pytest.approx(round(10 * private_run.completed / EPISODES, 2))
    assert {fast["rank"], slow["rank"]} <= {"1", "2"} and fast["late"] == slow["late"] == ""

    canvas = league("grades", title, "--format", "canvas", config=tmp_path, **env)
    lines = list(csv.reader(io.StringIO(canvas.stdout)))
    assert lines[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", title]
    assert lines[1][0] == "Points Possible" and {line[0] for line in lines[2:]} >= set(rows)
    moodle = league("grades", title, "--format", "moodle", config=tmp_path, **env)
    assert list(csv.reader(io.StringIO(moodle.stdout)))[:2] == [["Email address", title],
                                                                ["fast@uni.example", fast["points"]]]
    assert students["slow"]["name"] in moodle.stderr  # left out: no email

    student = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": students["fast"]["token"]}
    early = league("grades", title, config=tmp_path, **student)
    assert early.returncode == EXIT_REFUSED and f"the grades of {title} are not published" in early.stderr
    with sqlite_server.client(prof) as instructor:
        assert instructor.post(f"/api/assignments/{assignment['id']}/publish").status_code == 200
    mine = league("grades", title, config=tmp_path, **student)
    assert mine.returncode == EXIT_OK, mine.stderr
    assert mine.stdout.startswith(f"{title}: {float(fast['points']):g} / 10 points, rank {fast['rank']} of ")


def test_the_terminal_names_what_changed_and_says_when_an_upload_was_late(sqlite_server, models, tmp_path):
    """An instructor's commands say what they changed (create, edit, extend, publish, --set-rubric);
    a late upload is said late by `submit` and `submissions`; `--check` counts Canvas's matches."""
    from datetime import datetime, timedelta, timezone

    from league.client.output import local_time

    title, now = unique("Late"), datetime.now(timezone.utc)
    env = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": sqlite_server.instructor_token}
    due, late_until, extended = now - timedelta(minutes=5), now + timedelta(hours=2), now + timedelta(days=3)
    created = league("assignments", "create", title, "--due", due.isoformat(), "--late-until",
                     late_until.isoformat(), "--late-penalty", "0.5", "--episodes", "2", config=tmp_path, **env)
    assert created.returncode == EXIT_OK, created.stderr
    assert re.fullmatch(rf"assignment \d+: {title} created \(due {re.escape(local_time(due.isoformat()))}, late until "
                        rf"{re.escape(local_time(late_until.isoformat()))}, 2 episodes, public seed \d+\)\n",
                        created.stdout), created.stdout
    edited = league("assignments", "edit", title, "--episodes", "3", config=tmp_path, **env)
    assert edited.stdout == f"{title}: episodes 3 (was 2)\n", edited.stderr
    names = {who: unique(who) for who in ("punctual", "tardy")}
    tokens = {who: student_token(sqlite_server, name) for who, name in names.items()}
    extend = league("assignments", "extend", title, names["punctual"], "--due", extended.isoformat(),
                    config=tmp_path, **env)
    assert extend.stdout == (f"{title}: {names['punctual']} is now due {local_time(extended.isoformat())} "
                             f"(the assignment's due time: {local_time(due.isoformat())})\n"), extend.stderr

    student = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": tokens["tardy"]}
    late = league("submit", str(models["onnx"]), "--assignment", title, "--no-check", config=tmp_path, **student)
    assert late.returncode == EXIT_OK, late.stderr
    assert re.search(r"submission \d+: pending; late \(after your due time\): the late penalty applies if it is "
                     r"your final\n", late.stderr), late.stderr
    listed = league("submissions", "--csv", config=tmp_path, **student)
    assert [row["late"] for row in csv.DictReader(io.StringIO(listed.stdout))] == ["late"]
    on_time = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": tokens["punctual"]}  # their extension
    league("submit", str(models["onnx"]), "--assignment", title, "--no-check", config=tmp_path, **on_time)
    listed = league("submissions", "--csv", config=tmp_path, **on_time)
    assert [row["late"] for row in csv.DictReader(io.StringIO(listed.stdout))] == [""]

    (tmp_path / "rubric.json").write_text(json.dumps({"kind": "points", "max_points": 4,
                                                       "rank": {"kind": "linear", "points": 4}}))
    rubric = '{"kind":"points","max_points":4.0,"completed":null,"rank":{"kind":"linear","points":4.0}}'
    first = league("grades", title, "--set-rubric", str(tmp_path / "rubric.json"), config=tmp_path, **env)
    again = league("grades", title, "--set-rubric", str(tmp_path / "rubric.json"), config=tmp_path, **env)
    assert first.stdout.startswith(f"{title}: rubric set to {rubric} (was none)"), first.stdout
    assert again.stdout == f"{title}: rubric unchanged ({rubric})\n", again.stdout
    check = league("grades", title, "--format", "canvas", "--check", config=tmp_path, **env)
    assert check.returncode == EXIT_OK, check.stderr
    assert re.fullmatch(r"\d+ of \d+ rows carry an id Canvas matches \(ID, SIS User ID or SIS Login ID\); .*"
                        r"\d+ only a name, matched only if Canvas spells it the same: .*\n", check.stdout), check.stdout
    assert names["tardy"] in check.stdout.split("only a name")[1]  # created without ids
    wrong = league("grades", title, "--check", config=tmp_path, **env)
    assert wrong.returncode == EXIT_ERROR and "--format canvas --check" in wrong.stderr


def test_time_left_is_rounded_down_and_the_last_minute_is_under_a_minute():
    from league.client.assignments import time_left, upload_time_left

    now = "2026-12-01T12:00:00+00:00"
    assert [time_left(until, now) for until in ("2026-12-01T12:00:59+00:00", "2026-12-01T12:01:59+00:00",
                                                "2026-12-02T13:30:00+00:00", now, None)] == [
        "under a minute", "0h 1m", "1d 1h 30m", "passed", "no deadline"]
    assignment = {"now": now, "my_due_at": "2026-12-01T11:00:00+00:00", "my_closes_at": "2026-12-01T12:00:30+00:00"}
    assert upload_time_left({**assignment, "state": "late"}) == "late window: under a minute"
    assert upload_time_left({**assignment, "state": "closed"}) == "closed"


def _private_seed(server, token: str, assignment: dict) -> int:
    with server.client(token) as instructor:
        return instructor.get(f"/api/assignments/{assignment['id']}").json()["private_seed"]


def test_standings_by_name_for_members_and_names_that_name_none_or_several(sqlite_server, tmp_path):
    cup = unique("spring cup")
    member = {"LEAGUE_TOKEN": student_token(sqlite_server, unique("member"))}  # the boards are the members'
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        first = instructor.post("/api/championships", json={"name": cup}).json()["id"]
        table = league("standings", cup, "--server", sqlite_server.url, config=tmp_path, **member)
        assert table.returncode == EXIT_OK, table.stderr
        assert table.stdout.split() == ["rank", "student", "agent", "id", "points", "wins", "heats", "rating"]
        visitor = league("standings", cup, "--server", sqlite_server.url, config=tmp_path)  # no token
        assert visitor.returncode == EXIT_AUTH and "log in to see this" in visitor.stderr, visitor.stderr
        unknown = league("standings", "no such cup", "--server", sqlite_server.url, config=tmp_path, **member)
        assert unknown.returncode == 2 and "no championship named 'no such cup'; the championships: " in unknown.stderr
        assert f"{first} ({cup})" in unknown.stderr  # what there is to ask for
        second = instructor.post("/api/championships", json={"name": cup}).json()["id"]
    twice = league("standings", cup, "--server", sqlite_server.url, config=tmp_path, **member)
    assert twice.returncode == 2
    assert twice.stderr == (f"league: error: 2 championships are named {cup!r}: "
                            f"give the id of one of {first}, {second}\n")


def test_an_instructor_runs_a_championship_from_the_terminal_as_on_the_console(sqlite_server, models, tmp_path):
    """`league championships create|rounds|standings`: created with the console's fields, a round run
    and watched to its end with a bar of its heats, its standings read by a student (at the default
    visibility, members); the same championship as the API shows."""
    racer = unique("racer")
    student = create_student(sqlite_server, racer)
    uploaded = upload(student, models["onnx"], name="terminal car")
    assert uploaded.status_code == 201, uploaded.text
    assert wait_settled(student, uploaded.json()["id"], timeout=240)["status"] == "ready"
    baseline_submission(sqlite_server)
    teacher = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": sqlite_server.instructor_token}
    cup = unique("terminal cup")

    created = league("championships", "create", cup, "--heat-size", "4", "--points", "10,5,2", "--seed", "3",
                     "--no-obstacles", config=tmp_path, **teacher)
    assert created.returncode == EXIT_OK, created.stderr
    championship = int(created.stdout)
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        shown = instructor.get(f"/api/championships/{championship}").json()
    assert (shown["name"], shown["heat_size"], shown["points"], shown["seed"], shown["env_options"]["obstacles"],
            shown["include_baselines"]) == (cup, 4, [10, 5, 2], 3, False, True)

    ran = league("championships", "rounds", cup, "--run", config=tmp_path, **teacher)
    assert ran.returncode == EXIT_OK, ran.stderr
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        [over] = instructor.get(f"/api/championships/{championship}").json()["rounds"]
    heats = f"{over['heats_total']}/{over['heats_total']} heats"
    assert over["status"] == "done" and "round 1: done" in ran.stderr and heats in ran.stderr  # the bar's last state
    assert ran.stdout == f"round 1 is over ({heats} done); races {' '.join(map(str, over['race_ids']))}\n"
    listed = league("championships", "rounds", str(championship), "--csv", config=tmp_path, **teacher)
    [line] = csv.DictReader(io.StringIO(listed.stdout))
    assert (line["round"], line["status"], line["heats done"], line["races"]) == (
        "1", "done", heats.removesuffix(" heats"), " ".join(map(str, over["race_ids"])))

    reader = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": student_token(sqlite_server, unique("reader"))}
    standings = league("championships", "standings", cup, config=tmp_path, **reader)
    assert standings.returncode == EXIT_OK, standings.stderr
    assert racer in standings.stdout and "terminal car" in standings.stdout
    overview = league("championships", "--csv", config=tmp_path, **reader)
    assert [[c["championship"], c["rounds"], c["cars per heat"], c["assignment"], c["baselines"]]
            for c in csv.DictReader(io.StringIO(overview.stdout)) if c["id"] == str(championship)] == [
        [cup, "1", "4", "", "yes"]]
    refused = league("championships", "rounds", cup, "--run", config=tmp_path, **reader)
    assert (refused.returncode, refused.stderr) == (EXIT_AUTH, "league: error: the server refused: only instructors "
                                                              "may do this\n")


def test_a_bad_token_a_spent_quota_and_a_server_down_say_so(sqlite_server, models, tmp_path):
    old = student_token(sqlite_server, name := unique("renewed"))
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        user = next(u for u in instructor.get("/api/users").json() if u["name"] == name)
        assert instructor.post(f"/api/users/{user['id']}/token").status_code == 200  # a new token replaces it
    bad = league("submissions", "--server", sqlite_server.url, "--token", old, config=tmp_path)
    assert (bad.returncode, bad.stderr) == (EXIT_AUTH, f"league: error: the server refused the token: "
                                            f"{UNKNOWN_TOKEN}; once you have a new one: league login --server "
                                            f"{sqlite_server.url}\n")

    env = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": student_token(sqlite_server, unique("busy"))}
    for _ in range(int(TEST_SETTINGS["LEAGUE_QUOTA_PER_DAY"])):
        done = league("submit", str(models["heuristic_onnx"]), "--no-check", config=tmp_path, **env)
        assert done.returncode == EXIT_OK, done.stderr
    over = league("submit", str(models["heuristic_onnx"]), "--no-check", config=tmp_path, **env)
    assert over.returncode == EXIT_REFUSED
    said, refused = over.stderr.splitlines()
    # named before the upload: the only assignment open to a new student (on this server, as other tests left it)
    assert re.fullmatch(r"for the assignment \S+ \(the only one open to you\)", said), said
    assert refused.startswith("league: error: the server refused: quota reached: 4 submissions per 24 hours")

    down = f"http://127.0.0.1:{free_port()}"
    gone = league("submit", str(models["onnx"]), "--no-check", "--server", down, "--token", "lg_x", config=tmp_path)
    assert gone.returncode == EXIT_UNREACHABLE
    assert gone.stderr.startswith(f"league: error: cannot reach the league server at {down}: ")

    nothing = league("submissions", config=tmp_path)  # no login, no variables
    assert nothing.returncode == 2
    assert "no server: run `league login --server URL`" in nothing.stderr


def test_every_console_action_has_a_command_jobs_audit_rerun_privacy(sqlite_server, models, tmp_path):
    """What the console's Jobs, Audit, Re-run and Privacy panels do, from a terminal with the saved
    login (beside `league championships`, `assignments`, `grades`, `integrity`): each answer the API's."""
    teacher = {"LEAGUE_SERVER": sqlite_server.url, "LEAGUE_TOKEN": sqlite_server.instructor_token}
    student = create_student(sqlite_server, unique("clerk"))
    uploaded = upload(student, models["onnx"], name="audited car")
    assert uploaded.status_code == 201, uploaded.text
    submission_id = uploaded.json()["id"]
    assert wait_settled(student, submission_id, timeout=240)["status"] == "ready"

    listed = league("jobs", "--csv", "--limit", "1000", config=tmp_path, **teacher)
    assert listed.returncode == EXIT_OK, listed.stderr
    rows = list(csv.DictReader(io.StringIO(listed.stdout)))
    assert {(row["kind"], row["submission"]) for row in rows} >= {("validate", str(submission_id)),
                                                                   ("evaluate", str(submission_id))}
    with sqlite_server.client(sqlite_server.instructor_token) as instructor:
        assert [int(row["id"]) for row in rows] == [job["id"] for job in instructor.get(
            "/api/jobs", params={"limit": 1000}).json()]

    rerun = league("rerun", str(submission_id), config=tmp_path, **teacher)
    assert rerun.returncode == EXIT_OK, rerun.stderr
    assert rerun.stderr.strip() == f"1 evaluation queued again: submissions {submission_id}"
    queued = league("jobs", "--status", "queued", "--csv", config=tmp_path, **teacher)
    waiting = [row for row in csv.DictReader(io.StringIO(queued.stdout)) if row["submission"] == str(submission_id)]
    if waiting:  # (unless the worker took it already)
        cancelled = league("jobs", "--cancel", waiting[0]["id"], config=tmp_path, **teacher)
        assert cancelled.returncode == EXIT_OK, cancelled.stderr
        assert cancelled.stderr.startswith(f"job {waiting[0]['id']} (evaluate) cancelled")
    nothing = league("rerun", config=tmp_path, **teacher)
    assert nothing.returncode == EXIT_ERROR and "give a SUBMISSION id or --all" in nothing.stderr

    shown = league("privacy", config=tmp_path, **teacher)
    assert shown.stdout == "members\n"  # the default
    changed = league("privacy", "--board-visibility", "public", config=tmp_path, **teacher)
    assert changed.stderr.strip() == "board visibility: public (was members)"
    with sqlite_server.client() as visitor:
        assert visitor.get("/api/leaderboard").status_code == 200
    back = league("privacy", "--board-visibility", "members", config=tmp_path, **teacher)
    assert back.returncode == EXIT_OK, back.stderr
    refused = league("privacy", "--board-visibility", "public", config=tmp_path, LEAGUE_SERVER=sqlite_server.url,
                     LEAGUE_TOKEN=student.headers["authorization"].removeprefix("Bearer "))
    assert refused.returncode != EXIT_OK and "only instructors" in refused.stderr

    audit = league("audit", "--csv", config=tmp_path, **teacher)
    actions = [row["action"] for row in csv.DictReader(io.StringIO(audit.stdout))]
    assert "evaluation.rerun" in actions and actions.count("settings.privacy") >= 2
    table = league("audit", "--size", "5", config=tmp_path, **teacher)
    assert table.returncode == EXIT_OK and "settings.privacy" in table.stdout

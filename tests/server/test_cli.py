"""`league users ...` and the server commands in the toolkit's `league` CLI."""
from __future__ import annotations

import csv
import io
import os
import subprocess
import sys
from pathlib import Path

from league.cli import build_parser

from ..layout import REPO



def league(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "league.cli", *args], env=env, cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)


def test_league_cli_has_the_server_commands():
    parser = build_parser()
    assert parser.parse_args(["serve", "--host", "0.0.0.0", "--port", "9000"]).port == 9000
    assert parser.parse_args(["worker", "--threads", "2"]).threads == 2
    assert parser.parse_args(["users", "add", "ann", "--role", "student"]).role == "student"


def test_users_add_prints_a_token_once_and_names_are_unique(tmp_path):
    assert league(tmp_path, "init").returncode == 0
    added = league(tmp_path, "users", "add", "prof", "--role", "instructor")
    assert added.returncode == 0, added.stderr
    token = added.stdout.strip()
    assert token.startswith("lg_") and len(token) > 40
    stored = b"".join(p.read_bytes() for p in tmp_path.glob("league.db*"))
    assert token.encode() not in stored  # only its sha256 is kept

    again = league(tmp_path, "users", "add", "prof", "--role", "student")
    assert again.returncode == 1
    assert "user name 'prof' is already taken" in again.stderr

    student = league(tmp_path, "users", "add", "ann")  # student: the default role
    assert student.returncode == 0, student.stderr
    assert "created student 'ann'" in student.stderr

    assert league(tmp_path, "users", "revoke", "prof").returncode == 0
    listing = league(tmp_path, "users", "list").stdout
    assert "prof" in listing and "revoked" in listing
    assert [line.split()[1:3] for line in listing.splitlines() if " ann " in line] == [["ann", "student"]]


def test_init_prints_the_token_before_the_line_that_says_it_is_above(tmp_path):
    """stdout (the token) and stderr (what the command says) into one pipe, as a terminal shows them
    or `2>&1` keeps them: the token comes first, whatever the streams' buffering."""
    env = {**os.environ, "LEAGUE_DATA_DIR": str(tmp_path), "PYTHONPATH": str(REPO)}
    done = subprocess.run([sys.executable, "-m", "league.cli", "init", "--instructor", "prof"], env=env, cwd=tmp_path,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
    assert done.returncode == 0, done.stdout
    said = done.stdout.splitlines()
    token = next(index for index, line in enumerate(said) if line.startswith("lg_"))
    above = next(index for index, line in enumerate(said) if "the token above is shown once" in line)
    assert token < above, said


def test_users_import_creates_a_rosters_students_and_prints_their_tokens(tmp_path):
    """`league users import` reads rosters as the API does: the good lines' tokens as CSV on stdout,
    each other line with its number on stderr, exit 1 while a line has an error."""
    roster = tmp_path / "roster.csv"
    roster.write_bytes("\ufeffVorname;Nachname;E-Mail;Matrikelnummer\r\nNiaj;O'Brien;niaj@uni.de;0042\r\n"
                       "Zoë;Müller;zoe@uni;0043\r\n".encode())
    assert league(tmp_path, "init").returncode == 0
    first = league(tmp_path, "users", "import", str(roster))
    assert first.returncode == 1, first.stderr
    assert first.stdout.splitlines()[0] == "name,email,student_id,token"
    assert first.stdout.splitlines()[1].startswith('"Niaj O\'Brien","niaj@uni.de","0042","lg_')  # league.spreadsheet's
    created = list(csv.reader(io.StringIO(first.stdout)))[1:]
    assert [row[:3] for row in created] == [["Niaj O'Brien", "niaj@uni.de", "0042"]] and created[0][3].startswith("lg_")
    assert first.stderr.splitlines()[1:] == [  # after the line naming the database
        "line 3: error: the email 'zoe@uni' is not an address: The part after the @-sign is not valid. "
        "It should have a period.",
        "created 1 student, skipped 0 lines, 1 line with errors; the tokens above are shown once"]

    roster.write_bytes("Vorname;Nachname;E-Mail;Matrikelnummer\nNiaj;O'Brien;;0042\nZoë;Müller;zoe@uni.de;0043\n".encode())
    second = league(tmp_path, "users", "import", str(roster))
    assert second.returncode == 0, second.stderr
    assert [row[:3] for row in csv.reader(io.StringIO(second.stdout))] == [
        ["name", "email", "student_id"], ["Zoë Müller", "zoe@uni.de", "0043"]]
    assert second.stderr.splitlines()[1] == "line 2: skipped Niaj O'Brien: already a student (same student id)"
    missing = league(tmp_path, "users", "import", str(tmp_path / "nothing.csv"))
    assert missing.returncode == 1 and "nothing.csv: [Errno 2] No such file or directory" in missing.stderr


def test_a_worker_refuses_cpus_it_cannot_have(tmp_path):
    missing = league(tmp_path, "worker", "--cpus", "4096")
    assert missing.returncode == 2
    assert "--cpus '4096': CPU 4096 is not available here (this process may run on" in missing.stderr
    backwards = league(tmp_path, "worker", "--cpus", "3-1")
    assert backwards.returncode == 2
    assert "'3-1' is not a CPU number or range such as 2 or 0-3" in backwards.stderr


def test_nightly_backups_into_a_directory_keep_the_newest(tmp_path):
    """The compose file's backup service, as the host's cron runs it: `league backup --keep N DIR` writes a
    new dated file each time and deletes all but the N newest; each one restores."""
    assert league(tmp_path, "init").returncode == 0
    nightly = tmp_path / "nightly"
    nightly.mkdir()
    written = []
    for night in range(3):
        done = league(tmp_path, "backup", "--keep", "2", str(nightly))
        assert done.returncode == 0, done.stderr
        written.append(next(line.split()[4].rstrip(":") for line in done.stderr.splitlines() if "backed up to" in line))
        if night < 2:  # as if written on earlier nights (names are to the second)
            Path(written[-1]).rename(nightly / f"league-2026010{night}-030000.db")
    kept = sorted(path.name for path in nightly.iterdir())
    assert kept == ["league-20260101-030000.db", Path(written[-1]).name]
    restored = tmp_path / "restored"
    done = subprocess.run([sys.executable, "-m", "league.cli", "restore", str(nightly / kept[-1]), "--data-dir",
                           str(restored)], env={**os.environ, "PYTHONPATH": str(REPO)}, cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    refused = league(tmp_path, "backup", "--keep", "0", str(nightly))
    assert refused.returncode != 0 and "--keep takes a number of backups, at least 1" in refused.stderr


def test_courses_are_added_listed_and_given_their_instructors_and_students(tmp_path):
    """`league courses add|list`, `league users add|import --course`: each account lands in its course,
    and the new course's default assignment has its own evaluations of the baselines queued."""
    assert league(tmp_path, "init", "--instructor", "prof").returncode == 0
    added = league(tmp_path, "courses", "add", "RL 2027", "--instructor", "kim")
    assert added.returncode == 0, added.stderr
    assert added.stdout.strip().startswith("lg_")  # kim's token
    assert "created the course 'RL 2027'" in added.stderr and "created instructor 'kim'" in added.stderr
    again = league(tmp_path, "courses", "add", "RL 2027")
    assert (again.returncode, again.stderr.splitlines()[-1]) == (1, "league: error: a course named 'RL 2027' exists "
                                                                    "already")
    assert league(tmp_path, "users", "add", "ann", "--course", "RL 2027").returncode == 0
    assert league(tmp_path, "users", "add", "lee", "--course", "RL 2027", "--role", "instructor").returncode == 0
    assert league(tmp_path, "users", "add", "bo").returncode == 0  # the first course by default
    roster = tmp_path / "roster.csv"
    roster.write_text("name\nZoë Müller\n")
    assert league(tmp_path, "users", "import", str(roster), "--course", "RL 2027").returncode == 0
    unknown = league(tmp_path, "users", "add", "cy", "--course", "nope")
    assert unknown.returncode == 1 and "no course 'nope' (courses: default, RL 2027;" in unknown.stderr

    courses = [line.split(None, 1)[1] for line in league(tmp_path, "courses", "list").stdout.splitlines()]
    assert [line.split("  ")[0] for line in courses] == ["default", "RL 2027"]
    assert "1 instructor" in courses[0] and "1 student " in courses[0]
    assert "2 instructors" in courses[1] and "2 students " in courses[1]
    listing = {line.split()[1]: line.split()[2:] for line in league(tmp_path, "users", "list").stdout.splitlines()}
    assert listing["kim"] == ["instructor", "active", "RL", "2027"] and listing["ann"][-2:] == ["RL", "2027"]
    assert listing["bo"] == ["student", "active", "default"]

"""Privacy of the boards (league/server/course/privacy.py, deps.board_names): each visibility of a course
(public, members, instructors) against each viewer (a visitor, a student of another course, a
student of the course, its instructor) on every route of docs/CONTRACT.md that answers with
students' names or results; the body of every answer searched for the real names it must not hold.
And display names: set, validated, unique, shown to visitors of public boards instead of names."""
from __future__ import annotations

import gzip
import json
from dataclasses import dataclass

import pytest

from league.server.db import crud
from league.server.db.models import (
    DONE, INSTRUCTOR, Championship, ChampionshipRound, Course, Race, RaceReplay, User,
)
from league.server.course.privacy import pseudonym

from ...api_calls import unique
from ...backends import BACKENDS
from ..in_process import in_process_league


@dataclass
class Course_:
    """The first course (whose boards visitors are shown) with what its boards show, and viewers."""

    league: object
    tokens: dict[str, str]  # viewer -> token (anonymous: none)
    real_names: list[str]  # of the course's students: never in a public view
    display_name: str  # Ada's
    bob_pseudonym: str
    ids: dict[str, int]

    def client(self, viewer: str):
        return self.league.client(self.tokens.get(viewer))

    def set_visibility(self, visibility: str) -> None:
        with self.client("instructor") as instructor:
            response = instructor.put("/api/settings/privacy", json={"board_visibility": visibility})
        assert response.status_code == 200, response.text
        assert response.json() == {"board_visibility": visibility}


def finished_race(session, *, course: Course, entrants: list, order: list[int], **fields) -> Race:
    """A race as its job leaves it: classification, replay (cars named "agent (owner)"), log."""
    rows = [{"submission_id": s.id, "name": s.name, "owner": s.owner.name} for s in entrants]
    classification = [{"position": position, "car": f"car_{i}", **rows[i], "outcome": "finished",
                       "time": 10.0 + position, "distance": 1.0, "reason": None}
                      for position, i in enumerate(order, start=1)]
    race = Race(course_id=course.id, seed=1, env_options={}, entrants=rows, status=DONE,
                classification=classification, log="".join(f"== {r['name']} ({r['owner']}) ==\nhi\n" for r in rows),
                **fields)
    session.add(race)
    session.flush()
    names = [f"{r['name']} ({r['owner']})" for r in rows]
    replay = {"format": "microracer-replay", "version": 1, "seed": 1, "names": names,
              "classification": [{**row, "name": names[int(row["car"][4:])]} for row in classification]}
    session.add(RaceReplay(race_id=race.id, data=gzip.compress(json.dumps(replay).encode())))
    return race


@pytest.fixture(scope="module", params=BACKENDS)
def course(request, tmp_path_factory):
    with in_process_league(request.param, tmp_path_factory.mktemp(f"privacy-{request.param}")) as league:
        ada, ada_token = league.user("Ada Lovelace")
        bob, bob_token = league.user("Bob Babbage")
        _, cy_token = league.user("Cy Outsider", course_name=unique("other"))
        _, dee_token = league.user("Dee Otherprof", role=INSTRUCTOR, course_name=unique("other"))
        with league.client(ada_token) as client:
            display_name = unique("Speedy")
            assert client.patch("/api/users/me", json={"display_name": display_name}).status_code == 200
        with league.sessions() as session:
            baselines = crud.user_by_name(session, name=crud.BASELINES_USER)
        agents = [league.submission(owner, completed=c) for owner, c in ((ada, 3), (bob, 2), (baselines, 1))]
        with league.sessions.begin() as session:
            first = crud.first_course(session)
            entrants = [session.get(type(a), a.id) for a in agents]
            friendly = finished_race(session, course=first, entrants=[entrants[0], entrants[2]], order=[0, 1],
                                     created_by_id=ada.id)
            championship = Championship(course_id=first.id, name="Cup", env_options={}, heat_size=10,
                                        points=[3, 2, 1], include_baselines=True, seed=5)
            session.add(championship)
            session.flush()
            championship_round = ChampionshipRound(championship_id=championship.id, number=1, track_seed=7,
                                                   heats=[[a.id for a in agents]])
            session.add(championship_round)
            session.flush()
            heat = finished_race(session, course=first, entrants=entrants, order=[1, 0, 2],
                                 championship_id=championship.id, round_id=championship_round.id, heat=1)
            ids = {"friendly": friendly.id, "heat": heat.id, "championship": championship.id,
                   "ada_agent": agents[0].id}
            bob_number = session.get(User, bob.id).pseudonym
        yield Course_(league, {"ada": ada_token, "member": bob_token, "other": cy_token, "instructor":
                               league.instructor_token, "other instructor": dee_token},
                      [ada.name, bob.name], display_name, pseudonym(bob_number), ids)


VIEWERS = ["anonymous", "other", "member", "instructor"]
# every route answering with names or results of a course's students; "list": the viewer's own
# course's (a visitor: the first course's), "id": the first course's, by id
BOARD_ROUTES = {
    "/api/leaderboard": "list",
    "/api/races": "list",
    "/api/championships": "list",
    "/api/races/{friendly}": "id",
    "/api/races/{friendly}/replay": "id",
    "/api/races/{heat}": "id",
    "/api/races/{heat}/replay": "id",
    "/api/championships/{championship}": "id",
    "/api/championships/{championship}/rounds/1": "id",
    "/api/championships/{championship}/standings": "id",
}


def expected(visibility: str, viewer: str, route: str, how: str) -> tuple[int, str | None]:
    """(status, names shown: "real", "public", or None for an answer holding none of the course)."""
    if viewer == "instructor" or (viewer == "member" and visibility != "instructors"):
        return 200, "real"
    if viewer == "other" and how == "list":
        return 200, None  # their own course's board: nothing of the first course
    if visibility == "public":
        return 200, "public"
    if viewer == "member" and ("{heat}" in route or route == "/api/races"):
        return 200, "public"  # a race with their car (the list: those only), others under public names
    return (401 if viewer == "anonymous" else 403), None


@pytest.mark.parametrize("visibility", ["public", "members", "instructors"])
def test_each_visibility_shows_each_viewer_what_it_allows_and_no_real_name_beyond(course, visibility):
    course.set_visibility(visibility)
    for viewer in VIEWERS:
        for route, how in BOARD_ROUTES.items():
            path = route.format(**course.ids)
            status, names = expected(visibility, viewer, route, how)
            with course.client(viewer) as client:
                response = client.get(path)
            where = f"{viewer} GET {path} ({visibility})"
            assert response.status_code == status, f"{where}: {response.text}"
            body = response.text
            if status == 200 and names != "real":
                own = course.real_names[1] if viewer == "member" else None  # Bob's own name, in his races
                leaked = [name for name in course.real_names if name in body and name != own]
                assert not leaked, f"{where} shows {leaked}"
            if status == 401:
                assert response.json()["detail"].startswith("log in to see this: the boards of course"), where
                assert "anyone" not in response.json()["detail"]
            if status == 403:
                assert "the boards of course" in response.json()["detail"], where
            if names == "real" and "standings" in route:
                assert all(name in body for name in course.real_names), where


def test_a_public_board_shows_visitors_display_names_or_pseudonyms_and_baselines_as_they_are(course):
    course.set_visibility("public")
    with course.client("anonymous") as visitor:
        board = visitor.get("/api/leaderboard", params={"size": 100})
        standings = visitor.get(f"/api/championships/{course.ids['championship']}/standings").json()["items"]
        heat = visitor.get(f"/api/races/{course.ids['heat']}").json()
        replay = visitor.get(f"/api/races/{course.ids['heat']}/replay").json()
    assert board.headers["cache-control"] == "public, no-cache"
    owners = {row["owner"] for row in board.json()["items"]}
    assert {course.display_name, course.bob_pseudonym, crud.BASELINES_USER} <= owners
    assert [row["owner"] for row in standings] == [course.bob_pseudonym, course.display_name, crud.BASELINES_USER]
    assert [row["owner"] for row in heat["classification"]] == [course.bob_pseudonym, course.display_name,
                                                                 crud.BASELINES_USER]
    assert [name.rsplit(" (", 1)[1] for name in replay["names"]] == [
        f"{course.display_name})", f"{course.bob_pseudonym})", f"{crud.BASELINES_USER})"]
    with course.client("member") as member:  # the course's student: real names, not for proxies to keep
        board = member.get("/api/leaderboard", params={"size": 100})
    assert board.headers["cache-control"] == "private, no-cache"
    assert set(course.real_names) <= {row["owner"] for row in board.json()["items"]}


def test_a_student_sees_their_own_name_in_their_race_on_a_board_for_instructors(course):
    course.set_visibility("instructors")
    with course.client("ada") as ada:
        heat = ada.get(f"/api/races/{course.ids['heat']}").json()
        races = ada.get("/api/races").json()
        board = ada.get("/api/leaderboard")
    owners = [row["owner"] for row in heat["entrants"]]
    assert owners[0] == course.real_names[0] and owners[1] == course.bob_pseudonym
    assert sorted(race["id"] for race in races["items"]) == sorted([course.ids["friendly"], course.ids["heat"]])
    assert board.status_code == 403
    assert board.json() == {"detail": f"the boards of course {crud.DEFAULT_COURSE!r} are shown to the course's "
                                      f"instructors only; you are {course.real_names[0]!r} (student)"}


@pytest.mark.parametrize("visibility", ["public", "instructors"])
def test_grades_logs_and_others_submissions_are_for_the_courses_instructors_whatever_the_visibility(course,
                                                                                                   visibility):
    course.set_visibility(visibility)
    agent, friendly, cup = course.ids["ada_agent"], course.ids["friendly"], course.ids["championship"]
    paths = [f"/api/submissions/{agent}", f"/api/submissions/{agent}/episodes", "/api/leaderboard.csv",
             f"/api/races/{friendly}/log", f"/api/championships/{cup}/standings.csv"]
    refused = {"anonymous": 401, "other": (403, 404), "member": (403, 404), "other instructor": (403, 404)}
    for viewer, statuses in refused.items():
        for path in paths:
            with course.client(viewer) as client:
                response = client.get(path)
            if path == "/api/leaderboard.csv" and viewer == "other instructor":  # their own course's grades
                assert response.status_code == 200 and not any(n in response.text for n in course.real_names)
                continue
            assert response.status_code in (statuses if isinstance(statuses, tuple) else (statuses,)), \
                f"{viewer} GET {path}: {response.status_code}"
    with course.client("instructor") as instructor:
        assert all(instructor.get(path).status_code == 200 for path in paths)


def test_a_visibility_change_applies_to_the_next_request_and_only_instructors_make_it(course):
    course.set_visibility("public")
    with course.client("anonymous") as visitor:
        assert visitor.get("/api/leaderboard").status_code == 200
        course.set_visibility("members")
        assert visitor.get("/api/leaderboard").status_code == 401
    with course.client("member") as member:
        assert member.get("/api/settings/privacy").json() == {"board_visibility": "members"}
        refused = member.put("/api/settings/privacy", json={"board_visibility": "public"})
    assert refused.status_code == 403
    with course.client("instructor") as instructor:
        wrong = instructor.put("/api/settings/privacy", json={"board_visibility": "everyone"})
        audited = instructor.get("/api/audit").json()["items"][0]
    assert wrong.status_code == 422
    assert "board_visibility" in wrong.json()["detail"]
    assert (audited["action"], audited["details"]) == ("settings.privacy", {"board_visibility": "members",
                                                                            "was": "public"})


# --------------------------------------------------------------------------- display names


@pytest.mark.parametrize("display_name, status, detail", [
    ("", 200, None),
    (None, 200, None),
    ("  Zoë   O'Brien ", 200, None),
    ("x" * 101, 422, "the display name 'xxxxxxxxxxxxxxxxxxxx…' is too long: 101 characters, 100 at most"),
    ("=HYPERLINK(1)", 422, "the display name '=HYPERLINK(1)' holds"),
    ("Student 12", 422, "the display name 'Student 12' looks like the pseudonym of a student who has none"),
    ("baselines", 409, "the display name 'baselines' is taken: choose another"),
])
def test_display_names_are_validated_like_names(course, display_name, status, detail):
    with course.client("other") as student:
        response = student.patch("/api/users/me", json={"display_name": display_name})
    assert response.status_code == status, response.text
    if detail:
        assert response.json()["detail"].startswith(detail)
    else:
        assert response.json()["display_name"] == (" ".join(display_name.split()) if display_name else None)


def test_display_names_are_unique_in_a_course_and_never_another_accounts_name(course):
    with course.client("member") as bob:
        taken = bob.patch("/api/users/me", json={"display_name": course.display_name.upper()})
        real = bob.patch("/api/users/me", json={"display_name": course.real_names[0]})
        assert bob.get("/api/users/me").json()["display_name"] is None
    assert taken.status_code == real.status_code == 409
    assert taken.json()["detail"].endswith("is taken: choose another")
    with course.client("other") as elsewhere:  # another course: free there
        assert elsewhere.patch("/api/users/me", json={"display_name": course.display_name}).status_code == 200
        assert elsewhere.patch("/api/users/me", json={"display_name": None}).json()["display_name"] is None


def test_new_courses_take_the_setting_and_default_to_members(course):
    with course.league.sessions.begin() as session:
        default = crud.get_or_create_course(session, name=unique("new"), evaluation=course.league.settings
                                            .default_evaluation())
        public = crud.get_or_create_course(session, name=unique("new"), evaluation={"seed": 0, "episodes": 1,
                                           "env_options": {}}, board_visibility="public")
        assert (default.board_visibility, public.board_visibility) == ("members", "public")


OLD_MODULUS = 999_983  # the keyed permutation pseudonyms were before migration 0020


def affine_predictions(known: dict[int, int], modulus: int) -> dict[int, int] | None:
    """The attack on pseudonyms N = 1 + (a * id + b) mod m: a and b fitted from two known (id, N)
    pairs; returns the predictor's N for any id, or None if the pairs fix no a (no inverse mod m)."""
    (x1, y1), (x2, y2) = list(known.items())[:2]
    try:
        a = (y2 - y1) * pow(x2 - x1, -1, modulus) % modulus
    except ValueError:
        return None
    b = (y1 - 1 - a * x1) % modulus
    return lambda user_id: 1 + (a * user_id + b) % modulus


@pytest.mark.parametrize("backend", BACKENDS)
def test_pseudonyms_are_random_per_student_and_one_board_does_not_reveal_the_others_ids(backend, tmp_path):
    """A visitor of a public board who knows two students' ids (their own and a friend's) fits the
    affine map that used to make pseudonyms and predicts nobody else's; pseudonyms are distinct in
    the course, the same on every read, and those of a roster's students too."""
    with in_process_league(backend, tmp_path, bootstrap=False, board_visibility="public") as league:
        names = [unique(f"student{i:02d}") for i in range(30)]
        with league.client(league.instructor_token) as instructor:
            imported = instructor.post("/api/users/roster", files={"file": ("r.csv", "name\n" + "\n".join(names))})
        assert imported.status_code == 201, imported.text[:300]
        with league.sessions() as session:
            users = [crud.user_by_name(session, name=name) for name in names]
        owner_of = {league.submission(user).id: user.id for user in users}
        with league.client() as visitor:
            reads = [visitor.get("/api/leaderboard", params={"size": 100}).json()["items"] for _ in range(2)]
        with league.sessions() as session:
            stored = {user.id: session.get(User, user.id).pseudonym for user in users}
    shown = [{owner_of[row["submission_id"]]: int(pseudonym_text.split()[1]) for row in rows
              if (pseudonym_text := row["owner"]).startswith("Student ")} for rows in reads]
    assert shown[0] == shown[1] == stored and len(shown[0]) == 30
    assert len(set(stored.values())) == 30

    known = dict(list(shown[0].items())[:2])
    others = {user_id: number for user_id, number in shown[0].items() if user_id not in known}
    for modulus in (OLD_MODULUS, 999_999, 1_000_000):
        predict = affine_predictions(known, modulus)
        if predict is not None:
            assert [user_id for user_id, number in others.items() if predict(user_id) == number] == [], modulus
    # the same attack on the former pseudonyms predicts every one of them
    a, b = 123_457, 42
    former = {user_id: 1 + (a * user_id + b) % OLD_MODULUS for user_id in shown[0]}
    predict = affine_predictions(dict(list(former.items())[:2]), OLD_MODULUS)
    assert all(predict(user_id) == number for user_id, number in former.items())

"""Friendly races in process (the app on SQLite and on PostgreSQL, no worker): every race the API must
refuse is refused with a clear reason; unknown and failed races, page bounds, the replay's streaming.
Races a worker runs, reproducible from what is stored: tests/system/api/test_races.py."""
from __future__ import annotations

import gzip
import json
from types import SimpleNamespace

import pytest

from league.server.api.routes.races import gunzipped

from ...api_calls import not_raceable, post_race


@pytest.fixture(scope="module")
def app_grid(app_league):
    """alice's ready agent and rejected upload, and a ready baseline, as their jobs leave them."""
    from league.server.db import crud
    from league.server.db.models import REJECTED

    alice_user, alice = app_league.student("alice")
    with app_league.sessions() as session:
        baselines = crud.user_by_name(session, name=crud.BASELINES_USER)
    as_dict = lambda submission: {"id": submission.id}  # noqa: E731  (what these tests read of a submission)
    return SimpleNamespace(server=app_league, alice=alice, mine=as_dict(app_league.submission(alice_user)),
                           rejected=as_dict(app_league.submission(alice_user, status=REJECTED)),
                           baseline=as_dict(app_league.submission(baselines, public=True)))


# --------------------------------------------------------------------------- races and replays


@pytest.mark.parametrize("path", ["/api/races?page=9223372036854775808", "/api/leaderboard?page=100001",
                                  "/api/championships/1/standings?page=100001"])
def test_page_numbers_past_the_bound_are_refused(app_league, path):
    """Not a database error (an offset past 64 bits was a 500), nor a cache key of its own."""
    with app_league.client() as anonymous:
        response = anonymous.get(path)
    assert response.status_code == 422
    assert response.json() == {"detail": "query.page: Input should be less than or equal to 100000"}


def test_a_replay_is_sent_uncompressed_a_piece_at_a_time():
    """A client that takes no gzip gets the stored replay decompressed piece by piece, never whole."""
    replay = json.dumps({"cars": [{"x": [i / 7 for i in range(100_000)]}]}).encode()
    pieces = list(gunzipped(gzip.compress(replay), piece_size=64 * 1024))
    assert b"".join(pieces) == replay and len(pieces) > 10 and max(map(len, pieces)) == 64 * 1024


def test_unknown_races_are_404(app_grid):
    with app_grid.server.client() as anonymous:
        for path in ("/api/races/999999", "/api/races/999999/replay"):
            response = anonymous.get(path)
            assert response.status_code == 404
            assert response.json() == {"detail": "race 999999 does not exist"}


def test_a_failed_race_has_no_replay_and_says_why(app_league):
    """A race whose job failed for good (stored as the job machinery's give_up stores it)."""
    from league.server.db.models import FAILED, Race

    with app_league.sessions.begin() as session:
        race = Race(seed=1, env_options={}, entrants=[], status=FAILED,
                    error="the race could not be completed: gave up after 3 attempts")
        session.add(race)
        session.flush()
        race_id = race.id
    with app_league.student("reader")[1] as member:  # races are the members' (the default)
        assert member.get(f"/api/races/{race_id}").json()["status"] == "failed"
        response = member.get(f"/api/races/{race_id}/replay")
    assert response.status_code == 409
    assert response.json() == {"detail": f"race {race_id} failed, so it has no replay: "
                                         "the race could not be completed: gave up after 3 attempts"}


# --------------------------------------------------------------------------- refused races


def test_racing_an_unknown_submission_is_404(app_grid):
    response = post_race(app_grid.alice, [app_grid.mine["id"], 999999])
    assert response.status_code == 404
    assert response.json() == not_raceable(999999)


def test_racing_a_submission_that_is_not_ready_is_409(app_grid):
    rejected = app_grid.rejected["id"]
    response = post_race(app_grid.alice, [app_grid.mine["id"], rejected])
    assert response.status_code == 409
    assert response.json() == {"detail": f"submission {rejected} is not ready (status: rejected); "
                                         "only submissions that passed validation can race"}


def test_too_many_cars_is_422(app_grid):
    ids = [app_grid.mine["id"], app_grid.baseline["id"], *range(900001, 900010)]  # 11 > LEAGUE_MAX_RACE_CARS (10)
    response = post_race(app_grid.alice, ids)
    assert response.status_code == 422
    assert response.json() == {"detail": "too many cars: 11; a race takes at most 10"}


def test_a_submission_listed_twice_is_422(app_grid):
    response = post_race(app_grid.alice, [app_grid.mine["id"], app_grid.baseline["id"], app_grid.mine["id"]])
    assert response.status_code == 422
    assert response.json() == {"detail": f"submission {app_grid.mine['id']} is listed twice: "
                                         "each car races a different submission"}


def test_a_race_needs_two_cars(app_grid):
    response = post_race(app_grid.alice, [app_grid.mine["id"]])
    assert response.status_code == 422
    assert response.json() == {"detail": "submission_ids: List should have at least 2 items after validation, not 1"}


@pytest.mark.parametrize("options, detail", [
    ({"bogus": 1}, "invalid env_options: RaceOptions() got an unexpected keyword argument 'bogus'; valid options: "),
    ({"curves": 2}, "invalid env_options: curves must be an integer in [5, 60], got 2"),
    ({"curves": 1_000_000}, "invalid env_options: curves must be an integer in [5, 60], got 1000000"),
    ({"tstep": 1e-9}, "invalid env_options: tstep must be in [0.01, 0.2] seconds"),
    ({"max_episode_steps": 10**9}, "invalid env_options: max_episode_steps must be an integer in [1, 20000]"),
    ({"observation": "lidar"}, "observation is not an evaluation setting: it follows each agent's input size"),
])
def test_bad_env_options_are_422(app_grid, options, detail):
    response = post_race(app_grid.alice, [app_grid.mine["id"], app_grid.baseline["id"]], env_options=options)
    assert response.status_code == 422
    assert response.json()["detail"].startswith(detail)


def test_racing_without_a_token_is_401(app_grid):
    with app_grid.server.client() as anonymous:
        response = post_race(anonymous, [app_grid.mine["id"], app_grid.baseline["id"]])
    assert response.status_code == 401
    assert response.json() == {"detail": "missing token: send the header Authorization: Bearer TOKEN"}

import numpy as np
import pytest

from league.championship import DEFAULT_POINTS, Rating, heat_points, split_into_heats, standings, update_ratings


def names(n):
    return [f"s{i:02d}" for i in range(n)]


@pytest.mark.parametrize("n, heat_size, sizes", [(10, 10, [10]), (11, 10, [6, 5]), (40, 10, [10] * 4),
                                                 (41, 10, [9, 8, 8, 8, 8]), (3, 10, [3])])
def test_heats_are_balanced_in_size(n, heat_size, sizes):
    heats = split_into_heats(names(n), heat_size, np.random.default_rng(0))
    assert sorted(map(len, heats), reverse=True) == sizes
    assert sorted(sum(heats, [])) == names(n)


def test_heats_are_balanced_by_standing_with_a_snake():
    ranking = names(8)
    heats = split_into_heats(list(reversed(ranking)), 4, np.random.default_rng(0), ranking=ranking)
    assert heats == [["s00", "s03", "s04", "s07"], ["s01", "s02", "s05", "s06"]]


def test_heats_are_reproducible_from_the_seed():
    a = split_into_heats(names(30), 10, np.random.default_rng(5))
    b = split_into_heats(names(30), 10, np.random.default_rng(5))
    c = split_into_heats(names(30), 10, np.random.default_rng(6))
    assert a == b and a != c


def test_bad_heat_input():
    with pytest.raises(ValueError, match="heat_size"):
        split_into_heats(names(3), 0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="unique"):
        split_into_heats(["a", "a"], 5, np.random.default_rng(0))


def row(entrant, position, outcome="finished"):
    return {"entrant": entrant, "position": position, "outcome": outcome}


def test_points_follow_the_table_and_a_failed_agent_scores_nothing():
    classification = [row(f"e{p}", p, "finished" if p < 4 else "off_road") for p in range(1, 12)]
    classification[1]["outcome"] = "dnf"
    points = heat_points(classification)
    assert points["e1"] == 25 and points["e2"] == 0 and points["e3"] == 15 and points["e4"] == 12
    assert points["e10"] == 1 and points["e11"] == 0
    assert sum(points.values()) == sum(DEFAULT_POINTS) - 18


def test_standings_break_ties_by_wins_then_best_finishes():
    heats = [
        [row("a", 1), row("b", 2), row("c", 3)],  # a 25, b 18, c 15
        [row("b", 1), row("c", 2), row("a", 4)],  # b 25, c 18, a 12
        [row("c", 1), row("a", 2), row("b", 10)],  # c 25, a 18, b 1
    ]
    table = standings(heats)
    assert [(s.entrant, s.points, s.wins) for s in table] == [("c", 58, 1), ("a", 55, 1), ("b", 44, 1)]
    # equal points and wins: the one with more 2nd places is ahead
    tie = standings([[row("x", 1), row("y", 2)], [row("y", 1), row("z", 2)], [row("z", 1), row("x", 3)]],
                    table=(10, 10, 10))
    assert [s.entrant for s in tie] == ["y", "z", "x"]
    # countback compares equal depths: a 4th place beats no result at all
    depth = standings([[row("p", 1), row("q", 2)], [row("q", 1), row("p", 2)], [row("q", 4)]], table=(10, 10, 0, 0))
    assert [s.entrant for s in depth] == ["q", "p"]


def test_ratings_move_toward_the_order():
    ratings = update_ratings({}, ["a", "b", "c"])
    assert ratings["a"].mu > ratings["b"].mu > ratings["c"].mu
    assert all(r.sigma < Rating().sigma for r in ratings.values())
    again = update_ratings(ratings, ["c", "b", "a"])
    assert again["c"].mu > ratings["c"].mu and again["a"].mu < ratings["a"].mu
    assert Rating().conservative == pytest.approx(0.0)


def test_a_heat_of_one_entrant_leaves_its_rating_as_it_was():
    """3 entrants in heats of 2 make a heat of one: OpenSkill rates no single team, and nothing is
    learnt from it (the leaderboard answered 500 on such a round)."""
    heats = split_into_heats(["a", "b", "c"], 2, np.random.default_rng(3))
    assert sorted(map(len, heats)) == [1, 2]
    before = {"a": Rating(30.0, 5.0)}
    assert update_ratings(before, ["a"]) == {"a": Rating(30.0, 5.0)}
    assert update_ratings({}, ["z"]) == {"z": Rating()}

"""Championship rules: heats, points, standings and ratings.

Pure functions over plain data, so the league server's standings (league.server.course.standings) can
be recomputed at any time from the stored classifications.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

DEFAULT_POINTS = (25, 18, 15, 12, 10, 8, 6, 4, 2, 1)  # Formula 1's table


def split_into_heats(
    entrants: list[str], heat_size: int, rng: np.random.Generator, ranking: list[str] | None = None
) -> list[list[str]]:
    """Split entrants into heats of at most `heat_size`, balanced by current standing.

    Heats differ in size by at most one. Entrants are ordered by `ranking` (best first;
    unranked ones after, in random order), then dealt to the heats in a snake (A B C C B A ...)
    so every heat gets a similar mix of strong and weak entrants.
    """
    if heat_size < 1:
        raise ValueError(f"heat_size must be >= 1, got {heat_size}")
    if len(set(entrants)) != len(entrants):
        raise ValueError("entrants must be unique")
    if not entrants:
        return []
    position = {entrant: i for i, entrant in enumerate(ranking or [])}
    unranked = [e for e in entrants if e not in position]
    unranked = [unranked[i] for i in rng.permutation(len(unranked))]
    ordered = sorted((e for e in entrants if e in position), key=position.__getitem__) + unranked
    n_heats = math.ceil(len(entrants) / heat_size)
    heats: list[list[str]] = [[] for _ in range(n_heats)]
    for i, entrant in enumerate(ordered):
        lap, offset = divmod(i, n_heats)
        heats[offset if lap % 2 == 0 else n_heats - 1 - offset].append(entrant)
    return heats


def heat_points(classification: list[dict], table: tuple[int, ...] = DEFAULT_POINTS) -> dict[str, int]:
    """Points per entrant from a race classification (rows with "entrant", "position", "outcome").

    Every classified car scores by its position; an agent that failed ("dnf") scores nothing.
    """
    return {
        row["entrant"]: (table[row["position"] - 1] if row["position"] <= len(table) and row["outcome"] != "dnf" else 0)
        for row in classification
    }


@dataclass
class Standing:
    entrant: str
    points: int = 0
    finishes: list[int] = field(default_factory=list)  # positions, one per heat raced

    @property
    def wins(self) -> int:
        return self.finishes.count(1)

    def sort_key(self, depth: int):
        """Points, then wins, then best finishes: more 2nd places, then more 3rd places, ... (countback)."""
        return (-self.points, [-self.finishes.count(p) for p in range(1, depth + 1)], self.entrant)


def standings(heats: list[list[dict]], table: tuple[int, ...] = DEFAULT_POINTS) -> list[Standing]:
    """Championship standings from every heat's classification, best first.

    Ties on points are broken by wins, then by the count of best finishes (countback).
    """
    by_entrant: dict[str, Standing] = {}
    for classification in heats:
        points = heat_points(classification, table)
        for row in classification:
            standing = by_entrant.setdefault(row["entrant"], Standing(row["entrant"]))
            standing.points += points[row["entrant"]]
            standing.finishes.append(row["position"])
    depth = max((p for s in by_entrant.values() for p in s.finishes), default=0)
    return sorted(by_entrant.values(), key=lambda s: s.sort_key(depth))


@dataclass(frozen=True)
class Rating:
    mu: float = 25.0
    sigma: float = 25.0 / 3

    @property
    def conservative(self) -> float:
        """mu - 3 sigma: the skill we are 99.7 % sure the entrant has (what the leaderboard shows)."""
        return self.mu - 3 * self.sigma


def update_ratings(ratings: dict[str, Rating], order: list[str]) -> dict[str, Rating]:
    """OpenSkill (Plackett-Luce) ratings after one heat, `order` being its classification. A heat of
    one entrant (3 entrants in heats of 2 make one) compares no one: its rating stays as it was."""
    if len(order) < 2:
        return {e: ratings.get(e, Rating()) for e in order}
    from openskill.models import PlackettLuce

    model = PlackettLuce()
    teams = [[model.rating(mu=ratings.get(e, Rating()).mu, sigma=ratings.get(e, Rating()).sigma)] for e in order]
    rated = model.rate(teams, ranks=list(range(1, len(order) + 1)))
    return {e: Rating(team[0].mu, team[0].sigma) for e, team in zip(order, rated)}

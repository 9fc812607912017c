"""Standings, ratings and the course leaderboard, recomputed from what is stored.

Nothing here is stored: championship standings and OpenSkill ratings come from the finished
rounds' classifications, in order, with `league.championship` (the rules the toolkit uses too),
so every figure can be re-derived; the leaderboard from each submission's newest finished
evaluation of the current settings.
"""
from __future__ import annotations

from typing import Any

from sqlalchemy.orm import Session

from league import championship as rules
from league.server.course import results
from league.server.db import crud
from league.server.db.models import (
    BASELINE, DELETED, DONE, PUBLIC_TRACKS, STUDENT, Assignment, Championship, ChampionshipRound,
)


def finished_heats(rounds: list[ChampionshipRound]) -> list[list[dict]]:
    """The classifications of the heats of finished rounds, in order, as the rules read them."""
    heats = []
    for championship_round in sorted(rounds, key=lambda r: r.number):
        if championship_round.status != DONE:
            continue  # points are awarded when the whole round is over
        for race_row in championship_round.races:
            heats.append([{"entrant": row["submission_id"], "position": row["position"], "outcome": row["outcome"]}
                          for row in race_row.classification])
    return heats


def championship_standings(championship: Championship) -> list[rules.Standing]:
    return rules.standings(finished_heats(championship.rounds), tuple(championship.points))


def ratings_after(heats: list[list[dict]]) -> dict[int, rules.Rating]:
    """OpenSkill (Plackett-Luce) ratings, updated heat after heat from each heat's order."""
    ratings: dict[int, rules.Rating] = {}
    for heat in heats:
        order = [row["entrant"] for row in sorted(heat, key=lambda row: row["position"])]
        ratings.update(rules.update_ratings(ratings, order))
    return ratings


def standings_rows(session: Session, championship: Championship) -> list[dict]:
    heats = finished_heats(championship.rounds)
    table, ratings = rules.standings(heats, tuple(championship.points)), ratings_after(heats)
    submissions = crud.submissions_by_id(session, ids=[standing.entrant for standing in table])
    rows = []
    for rank, standing in enumerate(table, start=1):
        submission, rating = submissions.get(standing.entrant), ratings[standing.entrant]
        rows.append({"rank": rank, "submission_id": standing.entrant,
                     "name": submission.name if submission else DELETED,
                     "owner": submission.owner.name if submission else DELETED,
                     "owner_id": submission.owner_id if submission else None,
                     "owner_role": submission.owner.role if submission else None, "points": standing.points,
                     "wins": standing.wins, "finishes": standing.finishes, "rating": rating.conservative,
                     "mu": rating.mu, "sigma": rating.sigma})
    return rows


def course_heats(session: Session, *, course_id: int | None) -> list[list[dict]]:
    """The heats of every finished round of the course's championships, oldest first."""
    rounds = sorted((r for c in crud.course_championships(session, course_id=course_id) for r in c.rounds),
                    key=lambda r: r.id)
    heats = []
    for championship_round in rounds:
        heats += finished_heats([championship_round])
    return heats


def raced_last(session: Session, heats: list[list[dict]]) -> dict[int, int]:
    """Each owner's submission that raced last (owner id -> submission id)."""
    entrants = [row["entrant"] for heat in heats for row in heat]
    owners = {s.id: s.owner_id for s in crud.submissions_by_id(session, ids=sorted(set(entrants))).values()}
    return {owners[entrant]: entrant for entrant in entrants if entrant in owners}


# --------------------------------------------------------------------------- the course leaderboard


def leaderboard_rows(session: Session, *, course_id: int | None) -> list[dict]:
    """The public board of the course's default assignment (its oldest: /api/leaderboard)."""
    assignment = crud.default_assignment(session, course_id=course_id) if course_id is not None else None
    return [] if assignment is None else assignment_board(session, assignment)


def assignment_board(session: Session, assignment: Assignment, track: str = PUBLIC_TRACKS) -> list[dict]:
    """Each student's best evaluated submission of the assignment (completion rate, then mean return),
    and every bundled baseline as a reference row; best first, with the course-wide rating (a
    student's best agent that never raced shows the rating of their agent that raced last). Only
    results of the assignment's current settings rank (league.server.course.results); a student or baseline
    whose results are all of other settings follows the ranked rows, stale and unranked, by name.
    The private board (`track` PRIVATE_TRACKS; show it only once published) ranks the students' finals on
    the private tracks."""
    settings = assignment.evaluation_settings() if track == PUBLIC_TRACKS else assignment.private_settings()
    ranked: dict[tuple[str, int], Any] = {}
    stale: dict[tuple[str, int], Any] = {}
    # the newest finished evaluation: a re-run in progress does not take an agent off the board
    for entry in crud.leaderboard_entries(session, assignment=assignment, result_key=results.settings_key(settings),
                                          track=track):
        best, key = stale if entry.stale else ranked, leaderboard_key(entry)
        if key not in best or _score(entry) > _score(best[key]):
            best[key] = entry
    heats = course_heats(session, course_id=assignment.course_id)
    ratings, raced = ratings_after(heats), raced_last(session, heats)

    def rating(entry) -> rules.Rating | None:
        """The agent's; for a student whose best agent has not raced, that of their agent that raced last."""
        return ratings.get(entry.id) or ratings.get(raced.get(entry.owner_id))

    ordered = sorted(ranked.values(), key=lambda entry: (_score(entry), -entry.id), reverse=True)
    unranked = sorted((entry for key, entry in stale.items() if key not in ranked),
                      key=lambda entry: (entry.owner, entry.name, entry.id))
    return ([_leaderboard_row(rank, entry, rating(entry)) for rank, entry in enumerate(ordered, start=1)]
            + [_leaderboard_row(None, entry, rating(entry)) for entry in unranked])


def best_submissions(session: Session, assignment: Assignment, among: set[int] | None = None) -> dict[int, int]:
    """Each student's submission that stands best on the assignment's public board, by owner id: as
    assignment_board picks a student's row (their best ranked submission, else their best stale one;
    of equals, the newest), among the submissions of `among` only when given. The rule by which a
    final is chosen when the student selected none (league.server.course.assignments)."""
    best: dict[int, Any] = {}
    for entry in crud.leaderboard_entries(session, assignment=assignment, result_key=results.current_key(assignment)):
        if entry.owner_role != STUDENT or (among is not None and entry.id not in among):
            continue
        standing = (not entry.stale, *_score(entry))  # entries come newest first: an equal one does not win
        if entry.owner_id not in best or standing > best[entry.owner_id][0]:
            best[entry.owner_id] = (standing, entry.id)
    return {owner_id: submission_id for owner_id, (_, submission_id) in best.items()}


def leaderboard_key(entry) -> tuple[str, int]:
    """A row's identity: each baseline agent has a row, each student one (their best agent).
    Tagged, so that a student's user id never collides with a baseline's submission id."""
    if entry.owner_role == BASELINE:
        return ("baseline", entry.id)
    return ("student", entry.owner_id)


def _score(entry) -> tuple[float, float]:
    return (entry.completed / max(entry.episodes_total, 1), entry.mean_return)


def _leaderboard_row(rank: int | None, entry, rating: rules.Rating | None) -> dict:
    """`entry`: a row of crud.leaderboard_entries (a submission, its owner, its figures)."""
    return {"rank": rank, "stale": bool(entry.stale), "owner": entry.owner, "owner_id": entry.owner_id,
            "owner_role": entry.owner_role, "submission_id": entry.id, "name": entry.name,
            "public": entry.public, "completed": entry.completed, "episodes": entry.episodes_total,
            "mean_return": entry.mean_return, "mean_steps": entry.mean_steps,
            "mean_speed": entry.mean_speed, "rating": rating.conservative if rating else None,
            "mu": rating.mu if rating else None, "sigma": rating.sigma if rating else None}


# --------------------------------------------------------------------------- grades (CSV exports)


LEADERBOARD_GRADES = ["rank", "student", "agent", "submission_id", "completed", "episodes", "mean_return",
                      "mean_steps", "mean_speed", "rating", "stale", "revoked"]
STANDINGS_GRADES = ["rank", "student", "agent", "submission_id", "points", "wins", "heats", "rating", "mu", "sigma",
                    "revoked"]
STALE_FIGURES = ("rank", "completed", "episodes", "mean_return", "mean_steps", "mean_speed")  # empty when stale


def grade_rows(session: Session, rows: list[dict], *, course_id: int | None, columns: list[str]) -> list[list]:
    """The board's rows of the course's students, ranked among students only in the board's order
    (the baselines, left out, take no rank: the first student is 1), then every other student of
    the course with empty figures, revoked ones marked `revoked` = yes: one line per student to
    grade (or more, for standings, when their active submission changed between rounds). A stale
    row (its figures are of other settings) keeps its agent, is marked `stale` = yes and has its
    rank and figures empty, so that a gradebook never reads them as this course's."""
    students = [u for u in crud.course_users(session, course_id=course_id) if u.role == STUDENT]
    enrolled = {u.name for u in students}
    mine = [{**row, "student": row["owner"], "agent": row["name"], "heats": len(row.get("finishes", ())),
             **(dict.fromkeys(STALE_FIGURES) if row.get("stale") else {}), "stale": "yes" if row.get("stale") else None}
            for row in rows if row["owner"] in enrolled and row["submission_id"] > 0]  # < 0: a deleted student's
    for rank, row in enumerate((row for row in mine if row["rank"] is not None), start=1):
        row["rank"] = rank
    listed = {row["student"] for row in mine}
    mine += [{"student": u.name, "revoked": "yes" if u.revoked_at else None} for u in students if u.name not in listed]
    return [[row.get(column) for column in columns] for row in mine]

"""Races finished as their job would finish them, with outcomes made up by the test (the erasure tests:
the replay and the log name every car, so that what a deletion must scrub is there)."""
from __future__ import annotations

from sqlalchemy import select

from league.evaluation import league_versions
from league.server.db.models import Job, Race
from league.server.jobs.race import RaceOutcome, car_name


def outcome(race: Race, order: list[int]) -> RaceOutcome:
    """A race job's outcome, cars finishing in `order` (submission ids); the replay and log name every car."""
    by_id = {e["submission_id"]: (i, e) for i, e in enumerate(race.entrants)}
    rows = [{"position": p, "car": f"car_{by_id[i][0]}", **by_id[i][1], "outcome": "finished", "time": 10.0 + p,
             "distance": 100.0, "reason": None} for p, i in enumerate(order, start=1)]
    names = [car_name(e) for e in race.entrants]
    replay = {"names": names, "classification": [{**r, "name": car_name(r)} for r in rows],
              "versions": league_versions()}
    log = "".join(f"== {name} ==\nhello from {name}\n" for name in names)
    return RaceOutcome(rows, replay, None, log)


def finish_race(league, race_id: int, order: list[int]) -> None:
    with league.sessions() as session:
        race = session.get(Race, race_id)
        job_id = session.scalar(select(Job.id).where(Job.race_id == race_id))
        result = outcome(race, order)
    league.finish_job(job_id, result)

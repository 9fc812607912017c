"""The integrity report: submissions of different students that are one file, or one policy.

Two kinds of evidence, over a given list of submissions (a course's, an assignment's):

* files: the same sha256 as another student's submission, or as a bundled baseline (the files of
  the baselines' directories and the `baselines` account's submissions);
* behaviour: alike actions on a probe set (league.validation.probes): the public set, recorded in
  the sandbox that validated each upload, and each assignment's **secret** set, drawn on its
  private tracks and recorded by `secret_probe` jobs an instructor queues. The secret set is why a
  copy that answers the public set differently (it is in this repository) is still caught.

The behaviour distance does not compare action values but how one agent's actions follow the
other's (`behaviour_distances`): per action dimension, actions clipped to [-1, 1] (what the car
does), the residual of the best affine map from one agent's actions to the other's, as a fraction
of their spread: sqrt(1 - r^2), r their correlation over the probes (1 when r <= 0: a mirrored
answer is not a copy). It is also measured on the probes where neither agent sits at its own
extreme values, so a copy clipped tighter than its original is not told apart by the clipped
probes, and the smaller of the two counts. The largest over the two dimensions is the distance.
A copy rescaled (outputs x 0.98, the last layer x 1.03 under a tanh), offset, clipped, with
noise on its weights or re-exported stays within 0.05 of its original; the bundled baselines are
0.8 to 1 apart, and hand-made drivers that steer identically and hold different speeds 0.3 or
more (benchmarks/bench_integrity.py). Any pair's distance costs the same few matrix products, so
every pair is compared (the cost grows with the square of the submissions: 200 take ~30 ms). A
dimension that is constant for both agents says nothing (a constant answer is a trivial policy);
when every dimension is, their largest difference counts.

Submissions close on any probe set they share are linked; linked submissions form groups
(connected components); a group is reported when it holds the submissions of two students or
more, or of a student and a baseline. Nothing is blocked: an instructor reads the report.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from league.constants import OBSERVATION_DIMS
from league.server.db import crud
from league.server.db.models import (
    BASELINE, LOW, PROBE, QUEUED, READY, RUNNING, SECRET_PROBE, Assignment, Job, Submission, SubmissionProbe, User,
)
from league.validation.files import model_kind_of
from league.validation.probes import observations_key, probe_actions_from_bytes, probe_key, secret_probe_observations

IDENTICAL_FILE, SAME_BEHAVIOUR, BASELINE_COPY = "identical_file", "same_behaviour", "baseline_copy"
NOT_PROBED, PROBE_FAILED = "not yet probed", "the model failed on the probe set"
ROWS_AT_ONCE = 256  # rows of the distance matrix computed at once (256 x N float64 per statistic)
MIN_SPREAD = 1e-3  # an agent's actions on the probes vary less than this (standard deviation): constant
EDGE = 1e-4  # within this of an agent's own extreme value, an action may be clipped
MIN_SHARED = 16  # probes where neither agent is at an extreme, for that measure to count


@dataclass(frozen=True)
class Candidate:
    """A submission as the report reads it."""

    id: int
    name: str
    owner_id: int
    owner: str
    baseline: bool  # owned by the `baselines` account
    kind: str
    sha256: str
    obs_dim: int | None
    probe_key: str | None
    probe_actions: bytes | None
    created_at: datetime
    secret: tuple[tuple[str, bytes | None], ...] = ()  # (key, actions or None: failed) on secret sets recorded
    secret_keys: tuple[str, ...] = ()  # the secret sets it is compared on (its assignments')

    def probe_sets(self) -> dict[str, bytes | None]:
        """Its actions on the sets it should be compared on, recorded or not (missing keys)."""
        recorded = dict(self.secret)
        sets = {key: recorded[key] for key in self.secret_keys if key in recorded}
        public = _current_key(self)
        if public is not None and self.probe_key == public:
            sets[public] = self.probe_actions
        return sets

    def expected_keys(self) -> list[str]:
        public = _current_key(self)
        return ([public] if public is not None else []) + list(self.secret_keys)


@dataclass
class Group:
    kind: str
    members: list[Candidate]
    distance: float | None  # largest behaviour distance between its probed members (None: fewer than two)
    baseline: str | None = None  # the baseline copied (baseline_copy)

    @property
    def students(self) -> list[str]:
        return sorted({m.owner for m in self.members if not m.baseline})


@dataclass
class Report:
    tolerance: float
    compared: int  # submissions with actions on every probe set they are compared on
    groups: list[Group] = field(default_factory=list)
    unprobed: list[tuple[Candidate, str]] = field(default_factory=list)  # (submission, why)


def candidates(session: Session, *, course_id: int | None, assignment_id: int | None = None) -> list[Candidate]:
    """The ready submissions of a course's users and of the baselines; with `assignment_id`, those
    of one assignment and the baselines. Each with the secret sets of its assignment (a baseline:
    of `assignment_id`, or of every assignment of the course)."""
    owners = select(User.id).where((User.course_id == course_id) | (User.role == BASELINE))
    query = (select(Submission.id, Submission.name, Submission.owner_id, User.name, User.role == BASELINE,
                    Submission.kind, Submission.sha256, Submission.obs_dim, Submission.probe_key,
                    Submission.probe_actions, Submission.created_at, Submission.assignment_id)
             .join(User, Submission.owner_id == User.id)
             .where(Submission.owner_id.in_(owners), Submission.status == READY).order_by(Submission.id))
    if assignment_id is not None:
        query = query.where((Submission.assignment_id == assignment_id) | (User.role == BASELINE))
    rows = session.execute(query).all()
    recorded: dict[int, list[tuple[str, bytes | None]]] = {}
    for submission_id, key, actions in session.execute(
            select(SubmissionProbe.submission_id, SubmissionProbe.probe_key, SubmissionProbe.actions)
            .where(SubmissionProbe.submission_id.in_([row[0] for row in rows]))):
        recorded.setdefault(submission_id, []).append((key, actions))
    assignments = {a.id: a for a in session.scalars(select(Assignment).where(Assignment.course_id == course_id))}
    board = [assignments[assignment_id]] if assignment_id in assignments else list(assignments.values())
    found = []
    for *fields, own_assignment in rows:
        baseline, obs_dim = fields[4], fields[7]
        mine = board if baseline else [a for a in [assignments.get(own_assignment)] if a is not None]
        found.append(Candidate(*fields, secret=tuple(recorded.get(fields[0], ())),
                               secret_keys=tuple(secret_key(a, obs_dim) for a in mine if obs_dim in _DIMS)))
    return found


def secret_key(assignment: Assignment, obs_dim: int) -> str:
    """The key of an assignment's secret probe set for agents of `obs_dim` (its values stay here)."""
    return observations_key(secret_probe_observations(assignment.private_settings(), obs_dim))


def bundled_digests(directories: list[Path]) -> dict[str, str]:
    """sha256 -> file name of the model files in `directories` (the baselines' files)."""
    digests = {}
    for directory in directories:
        for path in sorted(directory.glob("*")) if directory.is_dir() else []:
            if path.is_file() and model_kind_of(path.name):
                digests.setdefault(hashlib.sha256(path.read_bytes()).hexdigest(), path.name)
    return digests


def integrity_report(submissions: list[Candidate], *, bundled: dict[str, str], tolerance: float) -> Report:
    """Groups of submissions of different students (or of a student and a baseline) that share a
    file or behave alike on a probe set; and the submissions whose behaviour is not fully known."""
    links = _UnionFind(len(submissions))
    first_of_digest: dict[str, int] = {}
    for i, submission in enumerate(submissions):
        links.union(i, first_of_digest.setdefault(submission.sha256, i))
    for indices, actions in _probed(submissions).values():
        for i, j in close_pairs(actions, tolerance):
            links.union(indices[i], indices[j])
    report = Report(tolerance, sum(_is_probed(s) for s in submissions))
    for component in links.components():
        group = _group([submissions[i] for i in component], bundled)
        if group is not None:
            report.groups.append(group)
    report.groups.sort(key=lambda g: (g.kind, g.members[0].id))
    report.unprobed = [(s, _why_unprobed(s)) for s in submissions if not _is_probed(s)]
    return report


def behaviour_distances(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(len(first), len(second)) behaviour distances (module docstring) between agents' actions
    (n, probes, 2) on one probe set, from sums over the probes that are matrix products: no
    loop over pairs or probes."""
    a, b = (np.clip(np.asarray(x, dtype=np.float64), -1, 1) for x in (first, second))
    distance = np.zeros((len(a), len(b)))
    all_flat = np.ones((len(a), len(b)), dtype=bool)
    for dim in range(a.shape[2]):
        x, y = a[:, :, dim], b[:, :, dim]
        residual, both_flat = _fit_residual_all(x, y)
        residual[both_flat] = 0.0  # no evidence either way from this dimension
        inside = _fit_residual_inside(x, _inside(x), y, _inside(y))
        distance = np.maximum(distance, np.minimum(residual, inside))
        all_flat &= both_flat
    if all_flat.any():  # constant answers both: their largest difference
        gap = np.abs(a.mean(axis=1)[:, None, :] - b.mean(axis=1)[None, :, :]).max(axis=2)
        distance[all_flat] = gap[all_flat]
    return distance


def _inside(x: np.ndarray) -> np.ndarray:
    """1 where an agent's action is not at (within EDGE of) its own smallest or largest value."""
    low, high = x.min(axis=1, keepdims=True), x.max(axis=1, keepdims=True)
    return ((x > low + EDGE) & (x < high - EDGE)).astype(np.float64)


def _standardised(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows centred and scaled to unit norm (their dot products are correlations); which are constant."""
    centred = x - x.mean(axis=1, keepdims=True)
    norm = np.sqrt((centred * centred).sum(axis=1, keepdims=True))
    flat = norm[:, 0] <= MIN_SPREAD * np.sqrt(x.shape[1])
    return centred / np.where(flat[:, None], 1.0, norm), flat


def _residual(r: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    residual = np.where(r > 0, np.sqrt(np.clip(1 - r * r, 0, None)), 1.0)
    residual[unknown] = 1.0
    return residual


def _fit_residual_all(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sqrt(1 - r^2) of each row of x against each row of y over every probe (1 where r <= 0 or
    one side is constant: one matrix product); and where both sides are constant."""
    (zx, flat_x), (zy, flat_y) = _standardised(x), _standardised(y)
    either, both = flat_x[:, None] | flat_y[None, :], flat_x[:, None] & flat_y[None, :]
    return _residual(zx @ zy.T, either), both


def _fit_residual_inside(x: np.ndarray, mx: np.ndarray, y: np.ndarray, my: np.ndarray) -> np.ndarray:
    """The same over the probes both masks keep (1 with fewer than MIN_SHARED of them, or one side
    constant there): the sums over those probes are matrix products of the masked rows."""
    first = (np.concatenate([mx, mx * x, mx * x * x]) @ my.T).reshape(3, len(x), len(y))
    second = (mx @ np.concatenate([my * y, my * y * y]).T).reshape(len(x), 2, len(y))
    n, sx, sxx, sy, syy = first[0], first[1], first[2], second[:, 0], second[:, 1]
    sxy = (mx * x) @ (my * y).T
    with np.errstate(invalid="ignore", divide="ignore"):
        vx, vy = sxx - sx * sx / n, syy - sy * sy / n  # n times the variances
        r = (sxy - sx * sy / n) / np.sqrt(vx * vy)
        unknown = ~(vx > n * MIN_SPREAD**2) | ~(vy > n * MIN_SPREAD**2) | (n < MIN_SHARED)
    return _residual(r, unknown)


def close_pairs(actions: np.ndarray, tolerance: float) -> list[tuple[int, int]]:
    """Pairs (i < j) of agents (rows of `actions`, (n, probes, 2)) within `tolerance` of each
    other's behaviour: the distance matrix ROWS_AT_ONCE rows at a time, its upper triangle kept."""
    actions = np.asarray(actions)
    close = []
    for start in range(0, len(actions), ROWS_AT_ONCE):
        block = behaviour_distances(actions[start:start + ROWS_AT_ONCE], actions)
        i, j = np.nonzero(block <= tolerance)
        i = i + start
        keep = j > i
        close += zip(i[keep].tolist(), j[keep].tolist())
    return close


def distance(a: Candidate, b: Candidate) -> float | None:
    """Their behaviour distance on the probe set where they are closest (None: they share none)."""
    sets_a, sets_b = a.probe_sets(), b.probe_sets()
    shared = [k for k in sets_a if k in sets_b and sets_a[k] is not None and sets_b[k] is not None]
    return min((float(behaviour_distances(probe_actions_from_bytes(sets_a[k])[None],
                                          probe_actions_from_bytes(sets_b[k])[None])[0, 0]) for k in shared),
               default=None)


def unprobed_submissions(session: Session, submissions: list[Candidate]) -> list[int]:
    """Ids of the submissions whose actions on the current public probe set are not recorded (nor
    failed) and that no probe job waits for or runs."""
    waiting = _waiting(session, PROBE)
    return [s.id for s in submissions if s.probe_key != _current_key(s) and s.id not in waiting]


def secret_unprobed_submissions(session: Session, submissions: list[Candidate]) -> list[int]:
    """Ids of the submissions without actions on a secret set they are compared on (an obs_dim
    known) that no secret probe job waits for or runs."""
    waiting = _waiting(session, SECRET_PROBE)
    recorded = {s.id: dict(s.secret) for s in submissions}
    return [s.id for s in submissions if s.id not in waiting
            and any(key not in recorded[s.id] for key in s.secret_keys)]


def queue_probes(session: Session, *, submission_ids: list[int], max_attempts: int) -> list[int]:
    """Low-priority probe jobs for these submissions (the caller enqueues them once committed)."""
    owners = dict(session.execute(select(Submission.id, Submission.owner_id)
                                  .where(Submission.id.in_(submission_ids))).tuples().all())
    return [crud.create_job(session, kind=PROBE, owner_id=owners[i], submission_id=i, max_attempts=max_attempts,
                            priority=LOW).id for i in submission_ids]


def queue_secret_probes(session: Session, *, submission_ids: list[int], instructor: User,
                        max_attempts: int) -> list[int]:
    """Low-priority secret probe jobs, the instructor's: in no student's job count, queue or log."""
    return [crud.create_job(session, kind=SECRET_PROBE, owner_id=instructor.id, submission_id=i,
                            max_attempts=max_attempts, priority=LOW).id for i in submission_ids]


_DIMS = set(OBSERVATION_DIMS.values())


def _waiting(session: Session, kind: str) -> set[int]:
    return set(session.scalars(select(Job.submission_id).where(Job.kind == kind, Job.status.in_((QUEUED, RUNNING)))))


def _current_key(submission: Candidate) -> str | None:
    return probe_key(submission.obs_dim) if submission.obs_dim in _DIMS else None


def _is_probed(submission: Candidate) -> bool:
    """Actions recorded on every set it is compared on."""
    sets = submission.probe_sets()
    return bool(sets) and all(sets.get(key) is not None for key in submission.expected_keys())


def _why_unprobed(submission: Candidate) -> str:
    sets = submission.probe_sets()
    return NOT_PROBED if any(key not in sets for key in submission.expected_keys()) else PROBE_FAILED


def _probed(submissions: list[Candidate]) -> dict[str, tuple[list[int], np.ndarray]]:
    """By probe set: the indices of the submissions with actions on it, and those actions (n, probes, 2)."""
    by_key: dict[str, tuple[list[int], list[np.ndarray]]] = {}
    for i, submission in enumerate(submissions):
        for key, actions in submission.probe_sets().items():
            if actions is not None:
                indices, rows = by_key.setdefault(key, ([], []))
                indices.append(i)
                rows.append(probe_actions_from_bytes(actions))
    return {key: (indices, np.stack(rows)) for key, (indices, rows) in by_key.items()}


def _group(members: list[Candidate], bundled: dict[str, str]) -> Group | None:
    students = {m.owner_id for m in members if not m.baseline}
    copied = next((m.name for m in members if m.baseline), None) or \
        next((bundled[m.sha256] for m in members if m.sha256 in bundled), None)
    if not students or (len(students) < 2 and copied is None):
        return None
    distances = [d for i, a in enumerate(members) for b in members[i + 1:] if (d := distance(a, b)) is not None]
    if copied is not None:
        kind = BASELINE_COPY
    else:
        kind = IDENTICAL_FILE if len({m.sha256 for m in members}) == 1 else SAME_BEHAVIOUR
    return Group(kind, members, max(distances, default=None), copied)


class _UnionFind:
    def __init__(self, n: int):
        self.parent = list(range(n))

    def find(self, i: int) -> int:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def union(self, i: int, j: int) -> None:
        self.parent[self.find(i)] = self.find(j)

    def components(self) -> list[list[int]]:
        groups: dict[int, list[int]] = {}
        for i in range(len(self.parent)):
            groups.setdefault(self.find(i), []).append(i)
        return list(groups.values())


def report_rows(report: Report) -> list[list[Any]]:
    """The CSV's lines: one per submission of each group, then the submissions not compared."""
    rows = []
    for number, group in enumerate(report.groups, 1):
        for m in group.members:
            rows.append([number, group.kind, group.distance, group.baseline, m.id, m.owner, m.name, m.kind,
                         m.sha256, m.created_at.isoformat(timespec="seconds"), None])
    for m, why in report.unprobed:
        rows.append([None, "not_compared", None, None, m.id, m.owner, m.name, m.kind, m.sha256,
                     m.created_at.isoformat(timespec="seconds"), why])
    return rows


CSV_COLUMNS = ["group", "kind", "distance", "baseline", "submission_id", "owner", "agent", "file_kind", "sha256",
               "uploaded_at", "note"]

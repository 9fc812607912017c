"""The integrity report: submissions of different students that are one file, or one policy.

Two kinds of evidence, over a given list of submissions (a course's, an assignment's):

* files: the same sha256 as another student's submission, or as a bundled baseline (the files of
  the baselines' directories and the `baselines` account's submissions);
* behaviour: the same actions on the probe set (league.validation.probes), recorded in the
  sandbox that validated each upload, within `tolerance` of each other: the largest difference of
  any of the 2 x 64 action values (max-abs). One network exported to ONNX and to TorchScript
  differs by float rounding (~2e-7); the bundled baselines differ from each other by 1.5 to 2
  (benchmarks/bench_integrity.py).

Submissions linked by either form groups (connected components); a group is reported when it
holds the submissions of two students or more, or of a student and a baseline. Nothing is blocked:
an instructor reads the report. It catches copies, not a determined student (noise added to the
weights changes the actions and the file).
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
from league.server.db.models import BASELINE, LOW, PROBE, QUEUED, READY, RUNNING, Job, Submission, User
from league.validation.files import model_kind_of
from league.validation.probes import probe_actions_from_bytes, probe_key

IDENTICAL_FILE, SAME_BEHAVIOUR, BASELINE_COPY = "identical_file", "same_behaviour", "baseline_copy"
NOT_PROBED, PROBE_FAILED = "not yet probed", "the model failed on the probe set"
PAIRS_AT_ONCE = 8192  # candidate pairs whose distances are computed at once (8192 x 128 float64: 8 MB)


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


@dataclass
class Group:
    kind: str
    members: list[Candidate]
    distance: float | None  # largest max-abs distance between its probed members (None: fewer than two)
    baseline: str | None = None  # the baseline copied (baseline_copy)

    @property
    def students(self) -> list[str]:
        return sorted({m.owner for m in self.members if not m.baseline})


@dataclass
class Report:
    tolerance: float
    compared: int  # submissions with actions on the current probe sets
    groups: list[Group] = field(default_factory=list)
    unprobed: list[tuple[Candidate, str]] = field(default_factory=list)  # (submission, why)


def candidates(session: Session, *, course_id: int | None, assignment_id: int | None = None) -> list[Candidate]:
    """The ready submissions of a course's users and of the baselines; with `assignment_id`, those
    of one assignment and the baselines (once submissions belong to assignments; ignored before)."""
    owners = select(User.id).where((User.course_id == course_id) | (User.role == BASELINE))
    query = (select(Submission.id, Submission.name, Submission.owner_id, User.name, User.role == BASELINE,
                    Submission.kind, Submission.sha256, Submission.obs_dim, Submission.probe_key,
                    Submission.probe_actions, Submission.created_at)
             .join(User, Submission.owner_id == User.id)
             .where(Submission.owner_id.in_(owners), Submission.status == READY).order_by(Submission.id))
    assignment = getattr(Submission, "assignment_id", None)
    if assignment_id is not None and assignment is not None:
        query = query.where((assignment == assignment_id) | (User.role == BASELINE))
    return [Candidate(*row) for row in session.execute(query)]


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
    file or behave alike on the probe set; and the submissions whose behaviour is not known."""
    links = _UnionFind(len(submissions))
    first_of_digest: dict[str, int] = {}
    for i, submission in enumerate(submissions):
        links.union(i, first_of_digest.setdefault(submission.sha256, i))
    probed = _probed(submissions)
    for indices in probed.values():
        for i, j in close_pairs(_action_matrix(submissions, indices), tolerance):
            links.union(indices[i], indices[j])
    report = Report(tolerance, sum(len(v) for v in probed.values()))
    for component in links.components():
        group = _group([submissions[i] for i in component], bundled)
        if group is not None:
            report.groups.append(group)
    report.groups.sort(key=lambda g: (g.kind, g.members[0].id))
    report.unprobed = [(s, NOT_PROBED if s.probe_key != _current_key(s) else PROBE_FAILED)
                       for s in submissions if not _is_probed(s)]
    return report


def close_pairs(matrix: np.ndarray, tolerance: float) -> list[tuple[int, int]]:
    """Pairs (i < j) of rows whose largest absolute difference is within `tolerance`.

    Two such rows have means within `tolerance` too (a mean moves no more than its largest term),
    so only the rows next to each other in the order of their means are compared: sorted, each
    row's candidates are those up to `tolerance` above its mean (numpy's searchsorted), and their
    max-abs distances are computed PAIRS_AT_ONCE pairs at a time. Exact; all pairs only when every
    mean is alike."""
    rows = np.asarray(matrix, dtype=np.float64)
    means = rows.mean(axis=1)
    order = np.argsort(means, kind="stable")
    rows, means = rows[order], means[order]
    ends = np.searchsorted(means, means + tolerance * (1 + 1e-9), side="right")
    counts = ends - np.arange(len(rows)) - 1  # candidates after each row
    first = np.repeat(np.arange(len(rows)), counts)
    second = first + 1 + np.arange(len(first)) - np.repeat(np.cumsum(counts) - counts, counts)
    close = []
    for start in range(0, len(first), PAIRS_AT_ONCE):
        i, j = first[start:start + PAIRS_AT_ONCE], second[start:start + PAIRS_AT_ONCE]
        near = np.abs(rows[i] - rows[j]).max(axis=1) <= tolerance
        close += zip(order[i[near]].tolist(), order[j[near]].tolist())
    return [(min(i, j), max(i, j)) for i, j in close]


def distance(a: Candidate, b: Candidate) -> float:
    return float(np.abs(probe_actions_from_bytes(a.probe_actions) - probe_actions_from_bytes(b.probe_actions)).max())


def unprobed_submissions(session: Session, submissions: list[Candidate]) -> list[int]:
    """Ids of the submissions whose actions on the current probe set are not recorded (nor failed)
    and that no probe job waits for or runs."""
    waiting = set(session.scalars(select(Job.submission_id).where(Job.kind == PROBE,
                                                                  Job.status.in_((QUEUED, RUNNING)))))
    return [s.id for s in submissions if s.probe_key != _current_key(s) and s.id not in waiting]


def queue_probes(session: Session, *, submission_ids: list[int], max_attempts: int) -> list[int]:
    """Low-priority probe jobs for these submissions (the caller enqueues them once committed)."""
    owners = dict(session.execute(select(Submission.id, Submission.owner_id)
                                  .where(Submission.id.in_(submission_ids))).tuples().all())
    return [crud.create_job(session, kind=PROBE, owner_id=owners[i], submission_id=i, max_attempts=max_attempts,
                            priority=LOW).id for i in submission_ids]


def _current_key(submission: Candidate) -> str | None:
    return probe_key(submission.obs_dim) if submission.obs_dim in OBSERVATION_DIMS.values() else None


def _is_probed(submission: Candidate) -> bool:
    return submission.probe_actions is not None and submission.probe_key == _current_key(submission)


def _probed(submissions: list[Candidate]) -> dict[str, list[int]]:
    """Indices of the submissions with actions on the current probe sets, by probe set."""
    by_key: dict[str, list[int]] = {}
    for i, submission in enumerate(submissions):
        if _is_probed(submission):
            by_key.setdefault(submission.probe_key, []).append(i)
    return by_key


def _action_matrix(submissions: list[Candidate], indices: list[int]) -> np.ndarray:
    return np.stack([probe_actions_from_bytes(submissions[i].probe_actions).ravel() for i in indices])


def _group(members: list[Candidate], bundled: dict[str, str]) -> Group | None:
    students = {m.owner_id for m in members if not m.baseline}
    copied = next((m.name for m in members if m.baseline), None) or \
        next((bundled[m.sha256] for m in members if m.sha256 in bundled), None)
    if not students or (len(students) < 2 and copied is None):
        return None
    probed = [m for m in members if _is_probed(m)]
    far = max((distance(a, b) for i, a in enumerate(probed) for b in probed[i + 1:]
               if a.probe_key == b.probe_key), default=None)
    if copied is not None:
        kind = BASELINE_COPY
    else:
        kind = IDENTICAL_FILE if len({m.sha256 for m in members}) == 1 else SAME_BEHAVIOUR
    return Group(kind, members, far, copied)


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

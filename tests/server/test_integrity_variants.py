"""Copies of a bundled baseline disguised as a student would (league.testing's builders, the onnx
package rewriting the baseline's own file), and honest agents, through the integrity report with
the default tolerance, on the public probe set and an assignment's secret one, the agents run in
this process as the sandbox runs them (the sandboxed path: tests/system/api/test_integrity.py)."""
from __future__ import annotations

import hashlib
import itertools
import zlib
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest

from league.agents import export_onnx, load_agent
from league.server.core.config import BUNDLED_BASELINES, Settings
from league.server.course.integrity import (
    BASELINE_COPY, Candidate, behaviour_distances, bundled_digests, integrity_report,
)
from league.testing import disguised_copies, thesis_driver
from league.validation.probes import (
    observations_key, probe_actions_bytes, probe_key, probe_observations, secret_probe_observations,
)

TOLERANCE = Settings().integrity_tolerance
PRIVATE = {"seed": 3_141_592_653, "episodes": 20, "env_options": {}}  # an assignment's private tracks
BASELINES = sorted(BUNDLED_BASELINES.glob("*.onnx"))
ids = itertools.count(1)

VARIANTS = disguised_copies()


def candidate(owner: str, path: Path, *, baseline: bool = False, name: str = "agent") -> Candidate:
    """A ready submission of `path` as the report reads it, its actions on both sets computed here."""
    agent = load_agent(path)
    public, secret = probe_observations(agent.obs_dim), secret_probe_observations(PRIVATE, agent.obs_dim)
    secret_key = observations_key(secret)
    return Candidate(next(ids), name, zlib.crc32(owner.encode()), owner, baseline, agent.kind,
                     hashlib.sha256(path.read_bytes()).hexdigest(), agent.obs_dim,
                     probe_key(agent.obs_dim), probe_actions_bytes(agent(public)),
                     datetime(2026, 11, 28, tzinfo=timezone.utc),
                     secret=((secret_key, probe_actions_bytes(agent(secret))),), secret_keys=(secret_key,))


def registered_baselines() -> list[Candidate]:
    return [candidate("baselines", path, baseline=True, name=path.stem) for path in BASELINES]


@pytest.mark.parametrize("source", ["ppo", "td3"])  # tanh and ReLU hidden layers
def test_every_disguised_copy_of_a_baseline_is_reported_as_that_baselines_copy(source, tmp_path):
    baselines = registered_baselines()
    students = {variant: candidate(f"student {n}", make(BUNDLED_BASELINES / f"{source}.onnx", tmp_path / f"v{n}"))
                for n, (variant, make) in enumerate(VARIANTS.items())}

    report = integrity_report([*baselines, *students.values()], bundled=bundled_digests([BUNDLED_BASELINES]),
                              tolerance=TOLERANCE)

    [group] = report.groups
    assert (group.kind, group.baseline) == (BASELINE_COPY, source)
    assert sorted(group.students) == sorted(s.owner for s in students.values())
    assert {m.name for m in group.members if m.baseline} == {source}  # no other baseline drawn in
    assert group.distance < TOLERANCE / 2 and report.unprobed == []


def test_the_probe_aware_copy_escapes_the_public_set_alone_and_not_the_secret_one(tmp_path):
    source = BUNDLED_BASELINES / "ppo.onnx"
    baseline, aware = candidate("baselines", source, baseline=True), candidate("ann", VARIANTS["probe-aware"](
        source, tmp_path / "aware"))
    public = [np.frombuffer(c.probe_actions, np.float32).reshape(1, -1, 2) for c in (baseline, aware)]
    secret = [np.frombuffer(c.secret[0][1], np.float32).reshape(1, -1, 2) for c in (baseline, aware)]
    assert behaviour_distances(*public)[0, 0] > TOLERANCE  # the public set is in this repository
    assert behaviour_distances(*secret)[0, 0] < 1e-5  # the private tracks are not


def test_honest_agents_are_not_reported(tmp_path):
    """The six bundled baselines uploaded by six students (none registered), and hand-made drivers
    that steer alike but hold other speeds: no group; the baselines stay far apart on both sets."""
    students = [candidate(f"student {path.stem}", path) for path in BASELINES]
    drivers = [candidate(f"driver {speed}", export_onnx(thesis_driver(seed=1, target_speed=speed),
                                                        tmp_path / f"{speed}.onnx"))
               for speed in (0.21, 0.25, 0.29, 0.37)]

    report = integrity_report(students + drivers, bundled={}, tolerance=TOLERANCE)

    assert report.groups == [] and report.compared == len(students) + len(drivers)
    for sets in ([c.probe_actions for c in students], [c.secret[0][1] for c in students]):
        actions = np.stack([np.frombuffer(a, np.float32).reshape(-1, 2) for a in sets])
        apart = behaviour_distances(actions, actions)[np.triu_indices(len(students), 1)]
        assert apart.min() > 5 * TOLERANCE, apart

"""The probe set the integrity report compares agents on: fixed, realistic, and telling agents apart."""
from __future__ import annotations

import numpy as np

from league.agents import compact_from_lidar, export_onnx, export_torchscript, load_agent
from league.constants import COMPACT_DIM, LIDAR_DIM
from league.testing import thesis_driver
from league.validation.probes import (
    PROBES, SECRET_PROBES, observations_key, probe_actions_bytes, probe_actions_from_bytes, probe_key,
    probe_observations, secret_probe_observations,
)


def test_the_probe_set_is_fixed_and_the_compact_one_is_the_lidar_one_seen_compactly():
    lidar, compact = probe_observations(LIDAR_DIM), probe_observations(COMPACT_DIM)
    assert lidar.shape == (PROBES, LIDAR_DIM) and compact.shape == (PROBES, COMPACT_DIM)
    assert lidar.dtype == compact.dtype == np.float32
    np.testing.assert_array_equal(lidar, probe_observations(LIDAR_DIM))  # the same set at every call
    np.testing.assert_array_equal(compact, compact_from_lidar(lidar))
    assert len(probe_key(LIDAR_DIM)) == 16 and probe_key(LIDAR_DIM) != probe_key(COMPACT_DIM)


def test_the_probe_set_holds_varied_situations():
    compact = probe_observations(COMPACT_DIM)
    speeds, directions = compact[:, 4], compact[:, 0]
    assert speeds.min() < 0.2 and speeds.max() > 0.35  # slow and fast cars
    assert (directions > 0.1).sum() >= 5 and (directions < -0.1).sum() >= 5  # curves both ways
    assert len(np.unique(compact, axis=0)) == PROBES


def test_one_network_exported_twice_agrees_and_another_does_not(tmp_path):
    net = thesis_driver(seed=3, target_speed=0.22)
    onnx_agent = load_agent(export_onnx(net, tmp_path / "a.onnx"))
    torchscript_agent = load_agent(export_torchscript(net, tmp_path / "a.pt"))
    other = load_agent(export_onnx(thesis_driver(seed=3, target_speed=0.27), tmp_path / "b.onnx"))
    obs = probe_observations(COMPACT_DIM)
    same = np.abs(onnx_agent(obs) - torchscript_agent(obs)).max()
    different = np.abs(onnx_agent(obs) - other(obs)).max()
    assert same < 1e-5 and different > 0.5, (same, different)


def test_actions_round_trip_through_their_stored_bytes():
    actions = np.random.default_rng(0).uniform(-1, 1, (PROBES, 2)).astype(np.float32)
    data = probe_actions_bytes(actions)
    assert len(data) == PROBES * 2 * 4
    np.testing.assert_array_equal(probe_actions_from_bytes(data), actions)


def test_an_assignments_secret_set_is_drawn_on_its_private_tracks_and_is_its_own():
    from league.env import MicroRacerEnv
    from league.evaluation import episode_seeds

    private = {"seed": 4_000_000_007, "episodes": 5, "env_options": {}}
    secret = secret_probe_observations(private, LIDAR_DIM)
    assert secret.shape == (SECRET_PROBES, LIDAR_DIM) and secret.dtype == np.float32
    np.testing.assert_array_equal(secret, secret_probe_observations(dict(private), LIDAR_DIM))  # the same each time
    np.testing.assert_array_equal(secret_probe_observations(private, COMPACT_DIM), compact_from_lidar(secret))
    starts = [MicroRacerEnv(observation="lidar").reset(seed=s)[0] for s in episode_seeds(private["seed"], 5)]
    picked_starts = [start for start in starts if (secret == start).all(axis=1).any()]
    assert len(picked_starts) >= 1  # a private track's start (each is kept once, before the draw)
    others = [secret_probe_observations(changed, LIDAR_DIM)
              for changed in ({**private, "seed": private["seed"] + 1}, {**private, "episodes": 6})]
    public = probe_observations(LIDAR_DIM)
    keys = {observations_key(s) for s in (secret, *others, public)}
    assert len(keys) == 4 and probe_key(LIDAR_DIM) in keys and len(np.unique(secret, axis=0)) == SECRET_PROBES

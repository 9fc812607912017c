"""Fidelity to the reference implementation: SPEC's heuristic driver on 150 seeded tracks."""
import numpy as np
import pytest

import league

from . import reference


def run_heuristic(episodes=150, **options):
    env = league.MicroRacerEnv(**options)
    outcomes, speeds = [], []
    for seed in range(episodes):
        obs, _ = env.reset(seed=seed)
        steps, speed_sum = 0, 0.0
        while True:
            obs, _, terminated, truncated, info = env.step(reference.heuristic(obs))
            steps += 1
            if terminated or truncated:
                break
            speed_sum += obs[4]
        outcomes.append(info["outcome"])
        speeds.append(speed_sum / steps)
    return np.mean([o == "finished" for o in outcomes]), float(np.mean(speeds))


def test_all_options_on_matches_the_reference():
    """Reference: 133/150 laps, mean speed 0.267."""
    completed, speed = run_heuristic()
    assert 0.80 <= completed <= 0.95, completed
    assert 0.25 <= speed <= 0.28, speed


def test_all_options_off_matches_the_reference():
    """Reference: 150/150 laps."""
    completed, _ = run_heuristic(obstacles=False, chicanes=False, turn_limit=False, low_speed_termination=False)
    assert completed >= 0.97, completed


@pytest.mark.parametrize("observation", ["lidar"])
def test_lidar_observation_drives_the_same(observation):
    # The heuristic on the compact features derived from the full lidar gives the same laps.
    env_c, env_l = league.MicroRacerEnv(), league.MicroRacerEnv(observation=observation)
    for seed in range(5):
        oc, _ = env_c.reset(seed=seed)
        ol, _ = env_l.reset(seed=seed)
        while True:
            action = reference.heuristic(oc)
            np.testing.assert_allclose(reference.compact(list(ol[:19]), ol[19]), oc, atol=1e-6)
            oc, rc, tc, uc, ic = env_c.step(action)
            ol, rl, tl, ul, il = env_l.step(action)
            assert (rc, tc, uc, ic) == (rl, tl, ul, il)
            if tc or uc:
                break

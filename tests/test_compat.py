"""league.compat: the thesis' Racer / newrun / metrics_run over the new code."""
import numpy as np
import pytest
from PIL import Image

import league
from league import compat, evaluation
from league.agents import heuristic_actions, heuristic_agent


def test_racer_reset_and_step_follow_the_thesis_interface():
    racer = compat.Racer(seed=7)
    state = racer.reset()
    assert state.shape == (5,) and state.dtype == np.float32
    env = league.MicroRacerEnv()
    expected, _ = env.reset(seed=7)
    np.testing.assert_array_equal(state, expected)
    total, done, steps = 0.0, False, 0
    while not done:
        state, reward, done = racer.step(heuristic_actions(state[None])[0])
        total, steps = total + reward, steps + 1
    episode = evaluation.run_episode(env, heuristic_agent(), 7)
    assert (steps, total) == (episode.steps, pytest.approx(episode.episode_return))
    assert racer.info["outcome"] == episode.outcome


def test_racer_options_reach_the_environment():
    racer = compat.Racer(obstacles=False, chicanes=False, turn_limit=False, low_speed_termination=False, seed=1)
    racer.reset()
    assert len(racer.track.obstacles) == 0
    assert racer.env.options.turn_limit is False


def test_metrics_run_prints_like_the_thesis_and_equals_the_new_one(capsys):
    result = compat.metrics_run(lambda states: heuristic_actions(np.asarray(states)), runs_num=4, seed=2,
                                obstacles=False)
    printed = capsys.readouterr().out.splitlines()
    assert len(printed) == 5 and printed[0].startswith("episode 0: steps ")
    assert printed[-1].startswith(f"completed {result.completed} / 4, mean return")
    expected = evaluation.metrics_run(heuristic_agent(), episodes=4, seed=2, obstacles=False)
    assert [e.to_dict() for e in result.episodes] == [e.to_dict() for e in expected.episodes]


def test_newrun_races_saves_and_survives_without_a_display(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.warns(UserWarning, match="no display"):
        result = compat.newrun(["heuristic", heuristic_agent()], seed=1, save=tmp_path / "race.gif")
    assert "race on seed 1" in capsys.readouterr().out
    assert [row["position"] for row in result.classification] == [1, 2]
    with Image.open(tmp_path / "race.gif") as gif:
        assert gif.n_frames > 10

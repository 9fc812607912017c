"""league.compat: the thesis' Racer / newrun / metrics_run (SPEC "The thesis' Python interface")."""
import numpy as np
import pytest
from PIL import Image

from gymnasium.utils import seeding

import league
from league import compat, evaluation
from league.agents import heuristic_actions, heuristic_agent

from . import reference


def thesis_actor(states):
    """A stand-in for the thesis' Keras actors: a batch of states in, a batch of actions out."""
    return heuristic_actions(np.asarray(states, dtype=np.float32))


def drive_until_done(racer, action):
    while True:
        state, reward, done = racer.step(action)
        if done:
            return state, reward


def test_racer_takes_the_thesis_options_in_the_thesis_order():
    racer = compat.Racer(True, False, False, False, seed=1)
    assert ((racer.obstacles, racer.turn_limit, racer.chicanes, racer.low_speed_termination)
            == (True, False, False, False))
    racer.reset()
    assert len(racer.obs_pos) == 6  # obstacles on
    assert len(racer.track.control_points) == 20  # no chicane: its five points replace one of the 20
    options = racer.env.options
    assert ((options.obstacles, options.turn_limit, options.chicanes, options.low_speed_termination)
            == (True, False, False, False))
    assert compat.Racer().chicanes and compat.Racer().turn_limit  # all on by default


def test_racer_has_the_thesis_attributes():
    racer = compat.Racer(seed=2)
    assert ((racer.curves, racer.tstep, racer.max_acc, racer.track_width, racer.obstacles_number)
            == (20, 0.04, 0.1, 0.04, 6))
    assert racer.max_turn == pytest.approx(np.pi / 6)
    state = racer.reset()
    assert (racer.done, racer.completation, racer.cartheta) == (False, 0, 0.0)
    assert (racer.carx, racer.cary) == pytest.approx(tuple(racer.cs(0)))
    assert np.hypot(racer.carvx, racer.carvy) == pytest.approx(racer.sinit_v) == pytest.approx(state[4])
    assert racer.sinit_v >= 0.07  # low-speed termination on
    assert racer.map.shape == (1300, 1300) and racer.map.dtype == bool
    assert racer.map[int(racer.carx * 500) + 650, int(racer.cary * 500) + 650]
    assert np.allclose(racer.csin(1.0), racer.track.inner(1.0))
    assert np.allclose(racer.csout(1.0), racer.track.outer(1.0))
    state, reward, done = racer.step([0.5, 0.2])
    assert np.arctan2(racer.cary, racer.carx) == pytest.approx(racer.cartheta)
    assert np.hypot(racer.carvx, racer.carvy) == pytest.approx(state[4])


def test_the_attributes_are_the_originals_and_writable_as_there():
    racer = compat.Racer(seed=2)
    assert {name: getattr(racer, name) for name in reference.THESIS_INIT_ATTRIBUTES} == pytest.approx(
        reference.THESIS_INIT_ATTRIBUTES)
    racer.reset()
    racer.step([0.1, 0.0])
    other = compat.Racer(seed=3)
    other.reset()
    written = {"curves": 12, "tstep": 0.03, "max_acc": 0.2, "max_turn": 0.4, "track_width": 0.05,
               "obstacles_number": 3, "obstacles": False, "chicanes": False, "turn_limit": False,
               "low_speed_termination": False, "cs": other.cs, "csin": other.csin, "csout": other.csout,
               "map": other.map, "obs_pos": other.obs_pos, "cartheta": -0.1, "carx": 0.9, "cary": -0.1,
               "carvx": 0.1, "carvy": -0.2, "done": True, "completation": 2, "sinit_v": 0.3, "max_turnrad": 0.1}
    names = [*reference.THESIS_INIT_ATTRIBUTES, *reference.THESIS_RESET_ATTRIBUTES, *reference.THESIS_STEP_ATTRIBUTES]
    assert sorted(written) == sorted(names)
    for name, value in written.items():
        setattr(racer, name, value)
    for name, value in written.items():
        assert getattr(racer, name) is value or getattr(racer, name) == pytest.approx(value), name
    with pytest.raises(ValueError, match="curves must be an integer in"):
        racer.curves = 2  # checked as the Racer's own arguments


def test_obs_pos_has_the_originals_layout_and_empty_value():
    racer = compat.Racer(seed=7)
    racer.reset()
    track, _, _ = reference.track_dict(seeding.np_random(7)[0])  # the track of reset(seed=7)
    expected = reference.thesis_obs_pos(np.array(track["obstacles"]))
    assert racer.obs_pos.shape == (6, 4) and np.allclose(racer.obs_pos, expected)
    racer = compat.Racer(False, seed=7)
    racer.reset()
    assert racer.obs_pos == [] == reference.thesis_obs_pos(np.zeros((0, 2, 2)))


def test_written_options_shape_the_next_track_and_physics_act_from_the_next_step():
    racer = compat.Racer(seed=8)
    racer.reset()
    racer.reset((racer.cs, racer.map, racer.obs_pos, 0.3))  # at speed 0.3
    racer.tstep, racer.max_acc, racer.max_turn, racer.turn_limit = 0.02, 0.5, 0.2, False
    heading, x, y = np.arctan2(racer.carvy, racer.carvx), racer.carx, racer.cary
    state, reward, _ = racer.step([1.0, 1.0])
    speed = 0.3 + 0.5 * 0.02
    assert state[4] == pytest.approx(speed) and reward == pytest.approx(speed * 0.02)
    assert np.arctan2(racer.carvy, racer.carvx) == pytest.approx(heading - 0.2) and racer.max_turnrad == 0.2
    assert (racer.carx, racer.cary) == pytest.approx((x + speed * 0.02 * np.cos(heading - 0.2),
                                                      y + speed * 0.02 * np.sin(heading - 0.2)))
    racer.turn_limit = True
    racer.step([0.0, 0.0])
    assert racer.max_turnrad == pytest.approx(min(0.2, 1.741 * 0.02 / speed))
    racer.low_speed_termination = False  # braking to a stop is no longer "too slow" (4)
    drive_until_done(racer, [-1.0, 0.0])
    assert racer.completation == 3  # standing still is no progress: wrong direction
    racer.curves, racer.chicanes, racer.obstacles_number, racer.track_width = 12, False, 2, 0.05
    racer.reset()
    assert len(racer.track.control_points) == 12 and len(racer.obs_pos) == 2 and racer.track.width == 0.05
    racer.obstacles = False
    racer.reset()
    assert racer.obs_pos == []


def test_written_car_state_is_where_the_next_step_starts():
    leader, follower = compat.Racer(seed=9), compat.Racer(seed=10)
    state = leader.reset()
    follower.reset((leader.cs, leader.map, leader.obs_pos, leader.sinit_v))
    for _ in range(5):
        state, *_ = leader.step(thesis_actor(state[None])[0])
    for name in ("carx", "cary", "carvx", "carvy", "cartheta"):
        setattr(follower, name, getattr(leader, name))
    action = thesis_actor(state[None])[0]
    a, b = leader.step(action), follower.step(action)
    np.testing.assert_allclose(a[0], b[0], rtol=1e-6)
    assert a[1] == pytest.approx(b[1]) and (leader.carx, leader.cary) == pytest.approx((follower.carx, follower.cary))


def test_a_written_map_is_where_the_car_drives_until_the_next_reset():
    racer = compat.Racer(seed=11)
    racer.reset()
    racer.step([0.0, 0.0])
    walled = racer.map.copy()
    i, j = int(racer.carx * 500) + 650, int(racer.cary * 500) + 650
    walled[i - 30:i + 31, j - 30:j + 31] = False  # the car's surroundings are off the map
    walled[i, j] = True
    racer.map = walled
    assert racer.map is walled
    state, reward, done = racer.step([0.0, 0.0])
    assert done and reward == -3 and racer.completation == 2
    racer.reset()
    assert racer.map is racer.track.valid


def test_max_turnrad_is_the_turn_bound_of_the_last_step():
    racer = compat.Racer(seed=3)
    racer.reset()
    for acc in (1.0, 0.5, -1.0):
        heading = racer.env.cars.heading[0]
        racer.step([acc, 1.0])  # full right: the heading turns by the whole bound
        assert heading - racer.env.cars.heading[0] == pytest.approx(racer.max_turnrad)
        assert racer.max_turnrad == pytest.approx(min(np.pi / 6, 1.741 * 0.04 / np.hypot(racer.carvx, racer.carvy)))


@pytest.mark.parametrize("options, speed, action, completation", [
    ({}, 0.3, [0.0, 1.0], 2),  # full right into the border: off road
    ({"low_speed_termination": False}, 0.0, [-1.0, 0.0], 3),  # standing still is no progress: wrong direction
    ({}, 0.07, [-1.0, 0.0], 4),  # braking below 0.05: too slow
])
def test_a_failure_returns_the_thesis_short_state(options, speed, action, completation):
    racer = compat.Racer(seed=4, **options)
    racer.reset()
    racer.reset((racer.cs, racer.map, racer.obs_pos, speed))
    state, reward = drive_until_done(racer, action)
    assert len(state) < 5 and np.array_equal(state, np.array([0]))  # the scripts' test for a failure
    assert reward == -3.0 and racer.done and racer.completation == completation


def test_a_completed_lap_returns_the_full_state():
    racer = compat.Racer(obstacles=False, seed=7)
    state = racer.reset()
    while True:
        state, reward, done = racer.step(thesis_actor(state[None])[0])
        if done:
            break
    assert racer.completation == 1 and len(state) == 5 and reward > 0
    assert racer.info["outcome"] == "finished"


def test_racer_continues_a_seeded_stream_and_otherwise_draws_from_numpys_global_generator():
    racer = compat.Racer(seed=7)
    expected, _ = league.MicroRacerEnv().reset(seed=7)
    np.testing.assert_array_equal(racer.reset(), expected)
    np.random.seed(11)
    first = [compat.Racer().reset() for _ in range(2)]
    np.random.seed(11)
    again = [compat.Racer().reset() for _ in range(2)]
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first[0], first[1])


def test_reset_with_a_shared_map_races_the_same_track_at_the_same_speed():
    leader, follower = compat.Racer(seed=5), compat.Racer(seed=6)
    state = leader.reset()
    shared = (leader.cs, leader.map, leader.obs_pos, leader.sinit_v)
    np.testing.assert_array_equal(follower.reset(shared), state)
    assert follower.track == leader.track and follower.sinit_v == leader.sinit_v
    for _ in range(50):
        action = thesis_actor(state[None])[0]
        a, b = leader.step(action), follower.step(action)
        np.testing.assert_array_equal(a[0], b[0])
        state = a[0]
        if a[2]:
            break
    changed = leader.map.copy()
    changed[650, :] = False
    with pytest.raises(ValueError, match="not the map of its cs and obs_pos"):
        follower.reset((leader.cs, changed, leader.obs_pos, leader.sinit_v))


def test_the_calls_of_the_thesis_training_scripts(monkeypatch, capsys):
    """Every call DDPG.py / TD3.py / SAC.py / PPO.py make on tracks.py, in their order and form."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    np.random.seed(0)
    racer = compat.Racer()  # racer = tracks.Racer()

    def step(action):  # the scripts' helper: sometimes a neutral action after the chosen one
        state, reward, done = racer.step(action)
        for _ in range(np.random.randint(0, 2)):
            if not done:
                state, t_r, done = racer.step([0, 0])
                reward += t_r
        return state, reward, done

    next_states, failures, crashes = np.zeros((2000, 5)), 0, 0
    index = 0
    for _ in range(8):
        prev_state = racer.reset()
        done = False
        while not done:
            action = thesis_actor(np.expand_dims(prev_state, 0))[0] * np.float32([1.0, 1.6])  # wobbly: some crash
            state, reward, done = step(action)
            fail = done and len(state) < 5
            next_states[index % 2000] = state  # the scripts' buffer: a short state broadcasts
            index += 1
            prev_state = state
        failures += fail
        crashes += racer.completation in (2, 3, 4)
    assert failures == crashes > 0  # every failure is stored as terminal

    result = compat.metrics_run(thesis_actor, 10)  # tracks.metrics_run(actor_model, 10)
    assert result.episodes_total == 10 and "completed" in capsys.readouterr().out
    with pytest.warns(UserWarning, match="no display"):
        race = compat.newrun([thesis_actor])  # tracks.newrun([actor_model])
    assert len(race.classification) == 1


def test_metrics_run_draws_fresh_tracks_unless_seeded(capsys):
    runs = [compat.metrics_run(thesis_actor, 2, verbose=False) for _ in range(2)]
    assert runs[0].settings["seed"] != runs[1].settings["seed"]
    np.random.seed(3)
    first = compat.metrics_run(thesis_actor, 2, verbose=False)
    np.random.seed(3)
    assert compat.metrics_run(thesis_actor, 2, verbose=False).to_dict() == first.to_dict()


def test_seeded_metrics_run_prints_like_the_thesis_and_equals_the_new_one(capsys):
    result = compat.metrics_run(thesis_actor, runs_num=4, seed=2, obstacles=False)
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

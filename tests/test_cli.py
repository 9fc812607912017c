"""The `league` command, end to end in subprocesses with no display."""
import json
import os
import shutil
import subprocess
import sys

import pytest
from PIL import Image

COMMANDS = ["evaluate", "race", "replay", "track"]


def league_cli(*args, cwd=None, timeout=120):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MPLBACKEND", "LEAGUE_DEBUG")}
    return subprocess.run([sys.executable, "-m", "league.cli", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=timeout)


def assert_clean_error(result, *fragments):
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("league: error:")]
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0]


@pytest.mark.parametrize("command", [[], *([c] for c in COMMANDS)])
def test_help_on_every_command(command):
    result = league_cli(*command, "--help")
    assert result.returncode == 0 and "usage: league" in result.stdout


def test_console_script_is_installed():
    script = shutil.which("league")
    if script is None:
        pytest.skip("the package is not installed (pip install -e .)")
    assert subprocess.run([script, "--help"], capture_output=True, text=True).returncode == 0


def test_evaluate_prints_a_table_with_progress(onnx_actor):
    result = league_cli("evaluate", onnx_actor, "--episodes", 5, "--seed", 3)
    assert result.returncode == 0, result.stderr
    assert "thesis_actor: 5 episodes, seed 3" in result.stdout and "completed" in result.stdout
    assert "5/5" in result.stderr  # the tqdm bar


def test_evaluate_json_matches_the_library(torchscript_actor):
    from league.agents import load_agent
    from league.evaluation import metrics_run

    result = league_cli("evaluate", torchscript_actor, "--episodes", 4, "--seed", 1, "--no-obstacles",
                        "--no-low-speed-termination", "--json", "--no-progress")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    expected = metrics_run(load_agent(torchscript_actor), episodes=4, seed=1, obstacles=False,
                           low_speed_termination=False).to_dict()
    assert data == json.loads(json.dumps(expected))
    assert data["settings"]["env_options"]["chicanes"] is True


def test_evaluate_a_bad_file_is_one_clear_line(tmp_path):
    bad = tmp_path / "actor.pt"
    bad.write_bytes(__import__("pickle").dumps([1, 2, 3]))
    assert_clean_error(league_cli("evaluate", bad), "actor.pt", "pickle")
    assert_clean_error(league_cli("evaluate", tmp_path / "missing.onnx"), "no such agent file")


def test_python_dash_m_league_exits_with_the_commands_status(tmp_path):
    result = subprocess.run([sys.executable, "-m", "league", "evaluate", str(tmp_path / "missing.onnx")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "no such agent file" in result.stderr


def test_output_into_a_pipe_whose_reader_quit_ends_quietly():
    """`league ... | head`: once the reader has quit, the command stops without a word, with the
    status SIGPIPE would give (141)."""
    for args in (["evaluate", "heuristic", "--episodes", "2", "--per-episode", "--no-progress"], ["--help"]):
        command = subprocess.Popen([sys.executable, "-m", "league", *args], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        command.stdout.close()  # the reader quits before the first line
        errors = command.stderr.read()
        expected = 0 if args == ["--help"] else 141  # argparse's help ends quietly too, with its own status
        assert (command.wait(timeout=120), errors) == (expected, ""), args
    head = subprocess.run(["sh", "-c", f"'{sys.executable}' -m league evaluate heuristic --episodes 3 --per-episode "
                                       "--no-progress | head -1"], capture_output=True, text=True, timeout=120)
    assert head.stdout.startswith("episode") and head.stdout.count("\n") == 1 and head.stderr == ""


def test_a_command_whose_extra_is_missing_says_which_extra_to_install():
    """`league leaderboard` without the client extra (platformdirs hidden here): one line naming the
    extra and the pip command, not an 'unexpected' error."""
    hide = ("import sys; sys.modules['platformdirs'] = None; from league.cli import main; "
            "sys.exit(main(['leaderboard', '--server', 'http://127.0.0.1:9']))")
    env = {k: v for k, v in os.environ.items() if k not in ("LEAGUE_DEBUG", "LEAGUE_SERVER", "LEAGUE_TOKEN")}
    result = subprocess.run([sys.executable, "-c", hide], capture_output=True, text=True, env=env, timeout=120)
    assert_clean_error(result, "platformdirs", "`client` extra", 'pip install "microracer-league[client]"')
    assert "unexpected" not in result.stderr


def test_race_saves_gif_and_replay_then_replay_saves_again(onnx_actor, tmp_path):
    result = league_cli("race", "heuristic", onnx_actor, "--seed", 1, "--save", "race.gif", "--replay", "race.json",
                        cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "race on seed 1" in result.stdout and "thesis_actor" in result.stdout and "heuristic" in result.stdout
    with Image.open(tmp_path / "race.gif") as gif:
        assert gif.format == "GIF" and gif.n_frames > 10
    replay = json.loads((tmp_path / "race.json").read_text())
    assert replay["names"] == ["heuristic", "thesis_actor"] and replay["seed"] == 1

    again = league_cli("replay", "race.json", "--save", "again.gif", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert again.stdout == result.stdout  # the same classification
    with Image.open(tmp_path / "again.gif") as gif:
        assert gif.n_frames > 10


def test_race_refuses_outputs_it_cannot_write_before_racing(tmp_path):
    assert_clean_error(league_cli("race", "heuristic", "--save", "race.png", cwd=tmp_path), "race.png", ".gif or .mp4")
    assert_clean_error(league_cli("race", "heuristic", "--replay", tmp_path / "no" / "r.json"), "does not exist")
    assert_clean_error(league_cli("race", "heuristic", "heuristic", "--names", "solo"), "--names gives 1 names for 2")


def test_show_without_a_display_says_to_save_instead():
    assert_clean_error(league_cli("race", "heuristic", "--show"), "no display", "--save")


def test_replay_of_a_missing_or_wrong_file(tmp_path):
    assert_clean_error(league_cli("replay", tmp_path / "none.json"), "no such replay file")
    (tmp_path / "notes.json").write_text("[1, 2]")
    assert_clean_error(league_cli("replay", tmp_path / "notes.json"), "not a MicroRacer replay")


def test_track_png_shows_the_race_track(tmp_path):
    result = league_cli("track", "--seed", 4, "--save", "track.png", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    with Image.open(tmp_path / "track.png") as image:
        assert image.format == "PNG"
    episode = league_cli("track", "--seed", 4, "--episode", 2, "--no-obstacles", "--save", "ep.png", cwd=tmp_path)
    assert episode.returncode == 0, episode.stderr
    assert_clean_error(league_cli("track", "--seed", 4), "--save track.png")


def test_a_waiting_command_looks_again_soon_then_once_a_second():
    """`league submit --wait`, `league race` and a watched round: an upload evaluated in a third of a
    second is seen within a few looks; a long wait asks the server once a second, as before."""
    import itertools

    from league.client.api import poll_delays

    delays = list(itertools.islice(poll_delays(), 12))
    assert delays[0] == 0.1 and delays == sorted(delays)
    assert sum(delays[:4]) < 1.0 and delays[-3:] == [1.0, 1.0, 1.0]

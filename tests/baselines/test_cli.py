"""`league train` / `league export` from the `league` command: resume, and one-line errors (exit 2)."""
import dataclasses
import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("torch")

from league.baselines import ALGORITHMS, load_algorithm
from league.baselines.cli import algorithm_parser

pytestmark = pytest.mark.slow  # trainings and `league` subprocesses: the full suite's tier


def cli(*args, timeout=120):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "MPLBACKEND", "LEAGUE_DEBUG")}
    return subprocess.run([sys.executable, "-m", "league.cli", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=timeout)


def assert_clean_error(result, *fragments):
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("league: error:")]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


QUICK = ["--learning-starts", 50, "--eval-every", 0, "--final-eval-episodes", 0, "--log-every", 50, "--no-progress"]


def test_bad_algorithm_name(tmp_path):
    assert_clean_error(cli("train", "sacc", "--out", tmp_path / "x"), "unknown algorithm 'sacc'", "sac", "ppo")
    assert not (tmp_path / "x").exists()


def test_unwritable_output_folder(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    assert_clean_error(cli("train", "sac", "--steps", 100, "--out", blocker / "run"), "cannot create the output folder")


def test_missing_run_to_resume(tmp_path):
    assert_clean_error(cli("train", "td3", "--resume", "--out", tmp_path / "nothing"), "no run to resume")


def test_a_new_run_never_overwrites_one_and_resume_checks_the_algorithm(tmp_path):
    out = tmp_path / "run"
    assert cli("train", "ddpg", "--steps", 100, "--out", out, *QUICK).returncode == 0
    assert_clean_error(cli("train", "ddpg", "--steps", 100, "--out", out, *QUICK), "already holds a run", "--resume")
    assert_clean_error(cli("train", "sac", "--resume", "--out", out), "holds a ddpg run")


def test_bad_option_values(tmp_path):
    assert_clean_error(cli("train", "sac", "--observation", "camera", "--out", tmp_path / "r"), "--observation")
    assert_clean_error(cli("train", "sac", "--envs", 0, "--out", tmp_path / "r"), "--envs must be at least 1")
    assert_clean_error(cli("train", "ddpg", "--lr-final-fraction", 2, "--out", tmp_path / "r"),
                       "--lr-final-fraction must be in [0, 1]")
    result = cli("train", "sac", "--no-such-option", "3")
    assert result.returncode == 2 and "unrecognized arguments: --no-such-option" in result.stderr


def test_resume_continues_from_the_checkpoint(tmp_path):
    out = tmp_path / "run"
    result = cli("train", "sac", "--steps", 200, "--checkpoint-every", 100, "--out", out, *QUICK)
    assert result.returncode == 0, result.stderr
    result = cli("train", "sac", "--resume", "--steps", 300, "--out", out)
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    config = json.loads((out / "config.json").read_text())
    assert summary["steps"] == 300
    assert config["args"]["learning_starts"] == 50 and config["args"]["steps"] == 300  # saved args, --steps new
    steps = [int(line.split(",")[0]) for line in (out / "losses.csv").read_text().splitlines()[1:]]
    assert steps == [100, 150, 200, 250, 300]  # rows up to the checkpoint kept once, then the new ones


def test_export_errors(tmp_path):
    assert_clean_error(cli("export", tmp_path, "--format", "onnx", "--out", tmp_path / "a.onnx"), "not a training run")
    out = tmp_path / "run"
    assert cli("train", "td3", "--steps", 100, "--out", out, *QUICK).returncode == 0
    assert_clean_error(cli("export", out, "--out", tmp_path / "missing" / "a.onnx"), "does not exist")
    result = cli("export", out, "--format", "torchscript", "--out", tmp_path / "td3.pt", "--which", "final")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "td3.pt").stat().st_size > 0


def test_help_lists_the_algorithm_options_with_their_help():
    result = cli("train", "sac", "--help")
    text = " ".join(result.stdout.split())  # argparse wraps the help
    assert result.returncode == 0
    assert "--policy-frequency" in text and "toward the target entropy -|A| (table 4.1) (default True)" in text
    assert "--neutral-prob" in text and "--resume" in text
    text = " ".join(cli("train", "ddpg", "--help").stdout.split())
    assert "--lr-final-fraction" in text and "(SB3's get_linear_fn; 1: constant, as the thesis) (default 0.0)" in text
    result = cli("train", "--help")
    assert result.returncode == 0 and "ddpg_param_noise" in result.stdout


def test_league_command_has_train_and_export():
    from league import cli as league_cli

    parser = league_cli.build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    assert "train" in commands and "export" in commands


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
def test_every_option_has_its_help_text(algorithm):
    args_class = load_algorithm(algorithm).Args
    options = {action.dest: action.help for action in algorithm_parser(algorithm, args_class)._actions}
    for field in dataclasses.fields(args_class):
        assert options[field.name].endswith(f" (default {field.default})")
        assert len(options[field.name]) > len(f" (default {field.default})") + 10, field.name

"""A student's first hour against a real server (`league serve` on SQLite, with its worker):

- the toolkit installed from the server's own package (GET /api/package, the command it gives)
  into a fresh venv of the system's Python, by an ordinary user, from the package index (with
  PIP_FIND_LINKS passed on, so that torch would stay the CPU build if anything asked for it);
  `league evaluate` there gives the server's figures for the same file on the same seed;
- `league check` in that venv, which has the onnx and client extras and not the server's: with no
  sqlite_server, and with a saved server that is down;
- every common export path (torch.onnx.export with its defaults, whose weights go beside the model,
  the legacy exporter, torch.jit.script, torch.jit.trace) checked, submitted, ready and evaluated
  with `league evaluate`'s figures.
"""
from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from league.exit_codes import EXIT_ERROR, EXIT_OK

from ..server.api_calls import unique
from ..server.backends import TEST_SETTINGS
from .ordinary import SYSTEM_PYTHON, require_root_tools, shared_directory
from .servers import student_token
from .students import Student, export, league, student_env

EPISODES, SEED = TEST_SETTINGS["LEAGUE_EVAL_EPISODES"], TEST_SETTINGS["LEAGUE_EVAL_SEED"]


# --------------------------------------------------------------------------- exports


def evaluated_table(result: subprocess.CompletedProcess) -> list[str]:
    """The figures of `league evaluate` (the table without its title line)."""
    assert result.returncode == EXIT_OK, result.stderr
    return result.stdout.splitlines()[1:]


EXPORTS = ["onnx", "onnx-legacy", "jit-script", "jit-trace"]


@pytest.mark.long
def test_every_common_export_is_checked_submitted_and_evaluated_as_league_evaluate_does(sqlite_server, tmp_path):
    """Each export checked (one `league check` of them all), then submitted and waited for (all at once,
    one student each) and evaluated here: the server's figures are `league evaluate`'s."""
    paths = {}
    for how in EXPORTS:
        (tmp_path / how).mkdir()
        paths[how] = export(how, tmp_path / how)
    assert (tmp_path / "onnx" / "policy.onnx.data").is_file()  # torch's default: the weights beside the model
    checked = league("check", *map(str, paths.values()), "--server", sqlite_server.url, config=tmp_path)
    assert checked.returncode == EXIT_OK, checked.stdout + checked.stderr
    lines = checked.stdout.splitlines()
    assert [line.split(":")[0] for line in lines] == [path.name for path in paths.values()]
    assert all(": the server would accept it: observation size 5" in line for line in lines), lines
    assert ["its weights in policy.onnx.data are packed in" in line for line in lines] == [True, False, False, False]

    submits = {how: subprocess.Popen(
        [sys.executable, "-m", "league.cli", "submit", str(path), "--wait", "--no-progress",
         "--server", sqlite_server.url, "--token", student_token(sqlite_server, unique(how))],
        cwd=tmp_path, env=student_env(tmp_path),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for how, path in paths.items()}
    for how, submit in submits.items():
        stdout, stderr = submit.communicate(timeout=600)
        assert submit.returncode == EXIT_OK, (how, stdout, stderr)
        evaluated = league("evaluate", str(paths[how]), "--episodes", EPISODES, "--seed", SEED, "--no-progress",
                           config=tmp_path)
        assert stdout.splitlines()[0].endswith(" is ready"), (how, stdout)
        assert stdout.splitlines()[2:] == evaluated_table(evaluated), how


# --------------------------------------------------------------------------- the student's own venv


@pytest.fixture(scope="module")
def student(sqlite_server):
    """The toolkit installed as the server says, in a fresh venv of an ordinary user."""
    require_root_tools()
    package = httpx.get(f"{sqlite_server.url}/api/package", timeout=120).json()
    wheel = next(file for file in package["files"] if file["kind"] == "wheel")
    with shared_directory() as root:
        student = Student(root)
        student.run(str(SYSTEM_PYTHON), "-m", "venv", str(student.venv))
        command = shlex.split(wheel["install"])
        assert command[:2] == ["pip", "install"] and command[2].startswith("microracer-league[onnx,client] @ http")
        student.run(*command, "-q")
        yield student


@pytest.mark.long
def test_a_fresh_venv_installs_the_servers_own_package_and_evaluates_as_the_server(sqlite_server, student, tmp_path):
    where = student.run("python", "-c", "import league; print(league.__file__, league.__version__)").stdout.split()
    served = httpx.get(f"{sqlite_server.url}/api/package").json()
    assert Path(where[0]).is_relative_to(student.venv) and where[1] == served["version"]
    installed = student.run("pip", "list", "--format=json").stdout
    assert not [p["name"] for p in json.loads(installed) if p["name"].startswith(("torch", "nvidia"))]

    model = student.give(export("onnx", tmp_path))
    token = student_token(sqlite_server, unique("fresh-venv"))
    evaluated = student.run("league", "evaluate", model.name, "--episodes", EPISODES, "--seed", SEED, "--no-progress")
    submitted = student.run("league", "submit", model.name, "--wait", "--no-progress", "--server", sqlite_server.url,
                            "--token", token)
    assert "its weights in policy.onnx.data are packed in" in submitted.stderr
    assert submitted.stdout.splitlines()[2:] == evaluated_table(evaluated)


@pytest.mark.long
def test_check_without_the_server_extra_alone_and_with_a_saved_server_that_is_down(student, tmp_path):
    no_server = student.run("python", "-c", "import league.server.core.config", expect=1)
    missing = no_server.stderr.rsplit("ModuleNotFoundError: No module named ", 1)[-1].strip("'\n")
    assert missing.split(".")[0] in ("pydantic", "pydantic_settings", "dotenv")  # the onnx and client extras only
    model = student.give(export("onnx", tmp_path))
    alone = student.run("league", "check", model.name)
    assert alone.stderr == "" and alone.stdout.startswith("policy.onnx: the server would accept it: observation "
                                                          "size 5")

    hidden = ("import sys; sys.modules['httpx'] = sys.modules['platformdirs'] = None; from league.cli import main; "
              "sys.exit(main(['check', 'policy.onnx']))")
    onnx_extra_only = student.run("python", "-c", hidden)  # as if the client extra were not installed
    assert onnx_extra_only.stdout.startswith("policy.onnx: the server would accept it") and not onnx_extra_only.stderr

    down = f"http://127.0.0.1:{_closed_port()}"
    saved = student.home / ".config" / "microracer-league" / "client.json"
    saved.parent.mkdir(parents=True, exist_ok=True)
    saved.write_text(json.dumps({"server": down, "token": "lg_saved"}))  # as `league login` saves it
    for path in (saved.parent.parent, saved.parent, saved):
        os.chown(path, student.uid, student.gid)
    offline = student.run("league", "check", model.name)
    assert offline.stdout == alone.stdout.replace(_figure(alone.stdout), _figure(offline.stdout))
    assert offline.stderr.startswith(f"cannot reach the league server at {down}: ")
    assert offline.stderr.rstrip().endswith("; checking against the league's default limits")

    scripted = student.give(export("jit-script", tmp_path))
    no_torch = student.run("league", "check", scripted.name, "--server", down, expect=EXIT_ERROR)
    assert "checking torchscript models here needs torch: pip install torch --index-url " \
           "https://download.pytorch.org/whl/cpu" in no_torch.stderr


def _figure(line: str) -> str:
    """The measured CPU time of a check's line (it differs from run to run)."""
    return line.split(", ")[1].split(" ms")[0]


def _closed_port() -> int:
    from .servers import free_port

    return free_port()


# --------------------------------------------------------------------------- Keras and TensorFlow

TENSORFLOW = ("tensorflow-cpu==2.21.0", "tf2onnx==1.17.0")  # pinned: a new release changes the test when we choose
TENSORFLOW_VENV = Path("/tmp/league-tensorflow-venv")  # never /tmp/league-venv: TensorFlow pins numpy and protobuf
# The thesis' DDPG actor (its section 4.1, "Implemented methods"): two towers of two 32-unit relu
# layers, each ending in one tanh unit (acceleration, direction), concatenated; exported both ways
# the guide shows.
KERAS_ACTOR = """
import keras
import numpy as np
from keras import layers

keras.utils.set_random_seed(0)
inputs = layers.Input(shape=(5,))
towers = []
for _ in range(2):
    out = layers.Dense(32, activation="relu")(inputs)
    out = layers.Dense(32, activation="relu")(out)
    towers.append(layers.Dense(1, activation="tanh")(out))
actor = keras.Model(inputs, layers.concatenate(towers), name="actor")
probe = np.random.default_rng(0).uniform(-1, 1, (16, 5)).astype(np.float32)
np.save("keras_actions.npy", actor.predict(probe, verbose=0))  # (a model is called once before its export)
actor.export("keras_actor.onnx", format="onnx")  # Keras 3's own route
actor.export("actor_savedmodel")  # a TensorFlow SavedModel, as the thesis' scripts save their actors
"""


@pytest.fixture(scope="module")
def tensorflow_python() -> Path:
    """A venv with tensorflow-cpu and tf2onnx (made once, kept between runs as the pins say)."""
    base_python = Path(sys.base_prefix) / "bin" / "python3"
    marker = TENSORFLOW_VENV / "league-requirements.txt"
    if not marker.exists() or marker.read_text() != "\n".join(TENSORFLOW):
        subprocess.run([str(base_python), "-m", "venv", "--clear", str(TENSORFLOW_VENV)], check=True)
        subprocess.run([str(TENSORFLOW_VENV / "bin" / "pip"), "install", "-q", *TENSORFLOW], check=True, timeout=1500)
        marker.write_text("\n".join(TENSORFLOW))
    return TENSORFLOW_VENV / "bin" / "python"


@pytest.mark.long
def test_the_thesis_keras_actor_goes_to_onnx_both_ways_and_is_evaluated_as_league_evaluate_does(
        sqlite_server, tensorflow_python, tmp_path):
    import numpy as np

    from league.agents import load_agent

    quiet = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3", "CUDA_VISIBLE_DEVICES": ""}
    subprocess.run([str(tensorflow_python), "-c", KERAS_ACTOR], cwd=tmp_path, env=quiet, check=True,
                   capture_output=True, timeout=600)
    subprocess.run([str(tensorflow_python), "-m", "tf2onnx.convert", "--saved-model", "actor_savedmodel",
                    "--output", "tf2onnx_actor.onnx"], cwd=tmp_path, env=quiet, check=True, capture_output=True,
                   timeout=600)
    probe = np.random.default_rng(0).uniform(-1, 1, (16, 5)).astype(np.float32)
    for name in ("keras_actor.onnx", "tf2onnx_actor.onnx"):
        path = tmp_path / name
        np.testing.assert_allclose(load_agent(path)(probe), np.load(tmp_path / "keras_actions.npy"), atol=1e-5)
        checked = league("check", str(path), "--server", sqlite_server.url, config=tmp_path)
        assert checked.returncode == EXIT_OK, checked.stdout + checked.stderr
        token = student_token(sqlite_server, unique("keras"))
        submitted = league("submit", str(path), "--wait", "--no-progress", "--server", sqlite_server.url,
                           "--token", token, config=tmp_path)
        assert submitted.returncode == EXIT_OK, submitted.stdout + submitted.stderr
        evaluated = league("evaluate", str(path), "--episodes", EPISODES, "--seed", SEED, "--no-progress",
                           config=tmp_path)
        assert submitted.stdout.splitlines()[2:] == evaluated_table(evaluated)
    refused = league("check", str(tmp_path / "actor_savedmodel"), config=tmp_path)
    assert "is a folder (a TensorFlow SavedModel), not a model file: convert it to ONNX first" in refused.stdout

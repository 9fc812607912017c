"""league.agents: loaders, the contract checks with their error messages, the heuristic driver."""
import math
import os
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from league import testing as models
from league.agents import (
    Agent,
    AgentError,
    as_agent,
    callable_agent,
    compact_from_lidar,
    export_heuristic_onnx,
    export_onnx,
    export_torchscript,
    heuristic_agent,
    import_onnxruntime,
    load_agent,
)

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")

RNG = np.random.default_rng(0)
OBS5 = RNG.uniform(0, 0.5, (8, 5)).astype(np.float32)
OBS5[:, 0] = RNG.uniform(-math.pi / 6, math.pi / 6, 8)
OBS5_LARGE = RNG.uniform(0, 0.5, (100, 5)).astype(np.float32)  # a batched evaluation's step
OBS5_LARGE[:, 0] = RNG.uniform(-math.pi / 6, math.pi / 6, 100)


def torch_actions(module, obs):
    with torch.no_grad():
        return module(torch.from_numpy(obs)).numpy()


# --------------------------------------------------------------------------- the heuristic driver


def test_heuristic_follows_spec_formula():
    obs = np.array([[0.2, 0.3, 0.4, 0.3, 0.20],  # free direction to the left, slow
                    [-0.1, 0.3, 0.4, 0.3, 0.25],  # to the right, at the target speed: brake
                    [math.pi / 6, 0.3, 0.4, 0.3, 0.30]], dtype=np.float32)
    actions = heuristic_agent()(obs)
    assert actions.dtype == np.float32 and actions.shape == (3, 2)
    np.testing.assert_allclose(actions[:, 0], [0.5, -0.2, -0.2])
    np.testing.assert_allclose(actions[:, 1], [-0.2 / (math.pi / 6), 0.1 / (math.pi / 6), -1.0], rtol=1e-6)


def test_heuristic_is_named_and_compact_by_default():
    agent = load_agent("heuristic")
    assert (agent.name, agent.obs_dim, agent.kind) == ("heuristic", 5, "heuristic")
    assert load_agent("heuristic-lidar").obs_dim == 20


def test_compact_features_from_lidar_follow_spec():
    rays = np.linspace(0.1, 0.2, 19)
    rays[7] = rays[12] = 0.9  # two maxima: the first one counts
    compact = compact_from_lidar(np.append(rays, 0.33)[None, :].astype(np.float32))[0]
    direction = -math.pi / 6 + 7 * (math.pi / 3) / 18
    np.testing.assert_allclose(compact, [direction, rays[6], 0.9, rays[8], 0.33], rtol=1e-6)


@pytest.mark.parametrize("k, left, right", [(0, 0, 1), (18, 17, 18)])
def test_compact_features_at_the_edges_repeat_the_maximum(k, left, right):
    rays = np.full(19, 0.1)
    rays[k] = 0.8
    compact = compact_from_lidar(np.append(rays, 0.2)[None, :].astype(np.float32))[0]
    assert compact[1] == pytest.approx(rays[k] if k == 0 else rays[left])
    assert compact[3] == pytest.approx(rays[k] if k == 18 else rays[right])


def test_heuristic_on_lidar_drives_as_on_compact():
    lidar = RNG.uniform(0, 0.6, (16, 20)).astype(np.float32)
    np.testing.assert_array_equal(heuristic_agent(20)(lidar), heuristic_agent(5)(compact_from_lidar(lidar)))


def test_heuristic_exported_to_onnx_drives_identically(tmp_path):
    agent = load_agent(export_heuristic_onnx(tmp_path / "heuristic.onnx"))
    assert agent.kind == "onnx"
    np.testing.assert_allclose(agent(OBS5), heuristic_agent()(OBS5), atol=1e-7)


# --------------------------------------------------------------------------- loading good models


def test_onnx_agent_reads_obs_dim_and_matches_torch(onnx_actor, thesis_module):
    agent = load_agent(onnx_actor)
    assert (agent.obs_dim, agent.name, agent.kind) == (5, "thesis_actor", "onnx")
    np.testing.assert_allclose(agent(OBS5), torch_actions(thesis_module, OBS5), atol=1e-6)


def test_torchscript_agent_matches_torch(torchscript_actor, thesis_module):
    agent = load_agent(torchscript_actor)
    assert (agent.obs_dim, agent.kind) == (5, "torchscript")
    np.testing.assert_allclose(agent(OBS5), torch_actions(thesis_module, OBS5), atol=1e-6)


def test_lidar_models_are_recognised(lidar_onnx_actor, tmp_path):
    assert load_agent(lidar_onnx_actor).obs_dim == 20
    torchscript = export_torchscript(models.thesis_driver(obs_dim=20), tmp_path / "lidar.pt")
    assert load_agent(torchscript).obs_dim == 20  # probed: 5 values fail, 20 work


def test_single_observation_is_a_batch_of_one(onnx_actor):
    assert load_agent(onnx_actor)(OBS5[0]).shape == (1, 2)


def export_fixed_to_one(module, path):
    """torch.onnx.export without a dynamic axis: input (1, 5), as many students export."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the legacy exporter needs no onnxscript; tracer warnings
        torch.onnx.export(module, (torch.zeros(1, 5),), str(path), dynamo=False)
    return path


def test_onnx_exported_with_a_fixed_batch_of_one_answers_a_batch_in_one_call(thesis_module, tmp_path):
    """Its graph does not depend on the batch: it is given a free batch dimension (one call per
    batch, not per row) and answers as the file's own graph answers each row."""
    path = export_fixed_to_one(thesis_module, tmp_path / "fixed.onnx")
    agent = load_agent(path)
    assert not agent.fixed_batch
    np.testing.assert_allclose(agent(OBS5_LARGE), torch_actions(thesis_module, OBS5_LARGE), atol=1e-6)
    session = import_onnxruntime().InferenceSession(str(path), providers=["CPUExecutionProvider"])
    as_exported = np.concatenate([session.run(None, {session.get_inputs()[0].name: OBS5_LARGE[k:k + 1]})[0]
                                  for k in range(len(OBS5_LARGE))])
    np.testing.assert_allclose(agent(OBS5_LARGE), np.clip(as_exported, -1, 1), rtol=0, atol=1e-6)


class ReshapesToOne(torch.nn.Module):
    def __init__(self, inner):
        super().__init__()
        self.inner = inner

    def forward(self, obs):
        return self.inner(obs.reshape(1, 5))


class MixesRows(torch.nn.Module):
    """The identity on a batch of one; on a larger batch, every row is shifted by the others."""

    def __init__(self, inner):
        super().__init__()
        self.inner = inner

    def forward(self, obs):
        return self.inner(obs + obs.sum(0, keepdim=True) - obs[0:1])


@pytest.mark.parametrize("wrapper", [ReshapesToOne, MixesRows])
def test_onnx_fixed_to_one_whose_graph_depends_on_the_batch_stays_row_by_row(wrapper, thesis_module, tmp_path):
    """A graph that fails on a batch, or answers it otherwise than row by row, is not given a free batch."""
    agent = load_agent(export_fixed_to_one(wrapper(thesis_module), tmp_path / "fixed.onnx"))
    assert agent.fixed_batch
    np.testing.assert_array_equal(agent(OBS5_LARGE), row_by_row(agent, OBS5_LARGE))
    np.testing.assert_allclose(agent(OBS5_LARGE), torch_actions(thesis_module, OBS5_LARGE), atol=1e-6)


def row_by_row(agent, obs):
    return np.concatenate([agent(obs[k:k + 1]) for k in range(len(obs))])


@pytest.mark.parametrize("kind", ["onnx", "torchscript"])
def test_dynamic_batch_models_answer_a_batch_in_one_call_as_row_by_row(kind, onnx_actor, torchscript_actor):
    agent = load_agent(onnx_actor if kind == "onnx" else torchscript_actor)
    assert not agent.fixed_batch
    obs = OBS5_LARGE
    # The same actions up to the last bits of float32 matmuls (the batched kernels sum in another order).
    np.testing.assert_allclose(agent(obs), row_by_row(agent, obs), rtol=0, atol=1e-6)


@pytest.mark.parametrize("kind", ["onnx", "torchscript"])
def test_models_fixed_to_batch_one_are_found_and_called_row_by_row(kind, thesis_module, tmp_path):
    module = models.BatchOfOne(thesis_module)
    if kind == "onnx":  # a dynamic batch axis is declared, but the graph reshapes to (1, 5)
        path = export_onnx(module, tmp_path / "one.onnx")
    else:
        path = export_torchscript(module, tmp_path / "one.pt")
    agent = load_agent(path)
    assert agent.fixed_batch and agent.obs_dim == 5
    np.testing.assert_array_equal(agent(OBS5_LARGE), row_by_row(agent, OBS5_LARGE))
    np.testing.assert_allclose(agent(OBS5_LARGE), torch_actions(thesis_module, OBS5_LARGE), atol=1e-6)


def test_a_failure_on_a_batch_is_isolable_and_names_the_model():
    def fails_on_fast_rows(obs):
        if (obs[:, 4] > 0.45).any():
            raise ValueError("bad input")
        return np.zeros((len(obs), 2))

    agent = callable_agent(fails_on_fast_rows, obs_dim=5)
    with pytest.raises(AgentError) as caught:
        agent(np.array([[0, 0.3, 0.3, 0.3, 0.2], [0, 0.3, 0.3, 0.3, 0.5]], dtype=np.float32))
    assert caught.value.isolable and caught.value.reason == "the model raised ValueError: bad input"
    assert not AgentError("the model used more than its 10 ms of CPU per observation").isolable


def test_several_outputs_use_the_first(thesis_module, tmp_path):
    two_heads = models.TwoHeads(thesis_module)
    expected = torch_actions(thesis_module, OBS5)
    onnx_agent = load_agent(export_onnx(two_heads, tmp_path / "two_heads.onnx"))
    script_agent = load_agent(export_torchscript(two_heads, tmp_path / "two_heads.pt"))
    for agent in (onnx_agent, script_agent):
        np.testing.assert_allclose(agent(OBS5), expected, atol=1e-6)


def test_actions_are_clipped():
    agent = callable_agent(lambda obs: np.tile([3.0, -7.5], (len(obs), 1)), obs_dim=5)
    np.testing.assert_array_equal(agent(OBS5), np.tile(np.float32([1.0, -1.0]), (8, 1)))


def test_as_agent_accepts_thesis_style_actors(thesis_module):
    expected = torch_actions(thesis_module, OBS5)

    class KerasLike:  # a Keras model is callable on numpy and returns its outputs as a list
        name = "keras_actor"

        def __call__(self, obs):
            return [torch_actions(thesis_module, np.asarray(obs)), np.zeros(len(obs))]

    class PredictOnly:
        def predict(self, obs):
            return torch_actions(thesis_module, obs)

    for actor in (thesis_module, KerasLike(), PredictOnly(), lambda obs: torch_actions(thesis_module, obs)):
        agent = as_agent(actor)
        assert isinstance(agent, Agent)
        np.testing.assert_allclose(agent(OBS5), expected, atol=1e-6)
    assert as_agent(KerasLike()).name == "keras_actor"


# --------------------------------------------------------------------------- bad files, clear reasons


def bad_file(kind, tmp_path, onnx_actor, torchscript_actor):
    path = tmp_path / {"random": "model.onnx", "random_pt": "model.pt", "pickle": "actor.pt",
                       "checkpoint": "checkpoint.pt", "truncated_pt": "cut.pt"}.get(kind, f"{kind}.onnx")
    if kind in ("random", "random_pt"):
        path.write_bytes(np.random.default_rng(1).bytes(2048))
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        models.truncated(onnx_actor, path)
    elif kind == "truncated_pt":
        models.truncated(torchscript_actor, path)
    elif kind == "pickle":
        models.pickle_renamed_pt(path)
    elif kind == "checkpoint":
        torch.save(models.thesis_driver(), path)
    else:
        options = {"wrong_input": {"in_dim": 7}, "three_outputs": {"out_dim": 3}, "nan_outputs": {"nan": True},
                   "integer_outputs": {"integer": True}}[kind]
        models.onnx_mlp(path, **options)
    return path


@pytest.mark.parametrize("kind, message", [
    ("random", "not an ONNX model"),
    ("random_pt", "not a TorchScript file"),
    ("empty", "is empty"),
    ("truncated", "truncated"),
    ("truncated_pt", "truncated"),
    ("wrong_input", "wrong input size: the model takes 7 values"),
    ("three_outputs", "returns 3 values per observation, expected 2"),
    ("nan_outputs", "NaN"),
    ("integer_outputs", "not floating point"),
    ("pickle", "is a Python pickle, not TorchScript"),
    ("checkpoint", "torch.save checkpoint (a pickle), not TorchScript"),
])
def test_bad_files_are_rejected_with_a_clear_reason(kind, message, tmp_path, onnx_actor, torchscript_actor):
    path = bad_file(kind, tmp_path, onnx_actor, torchscript_actor)
    with pytest.raises(AgentError) as caught:
        load_agent(path)
    assert message in caught.value.reason
    assert "\n" not in caught.value.reason


def test_pickles_are_refused_before_anything_unpickles_them(tmp_path):
    # A pickle whose loading would write a file: refusing it must leave no trace.
    marker = tmp_path / "pwned"

    class Exploit:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    path = tmp_path / "exploit.pt"
    path.write_bytes(__import__("pickle").dumps(Exploit()))
    with pytest.raises(AgentError, match="pickle"):
        load_agent(path)
    assert not marker.exists()


def test_torchscript_with_a_wrong_input_size(tmp_path):
    module = torch.nn.Sequential(torch.nn.Linear(7, 2), torch.nn.Tanh())
    with pytest.raises(AgentError, match="wrong input size"):
        load_agent(export_torchscript(module, tmp_path / "seven.pt"))


def test_torchscript_with_three_outputs(tmp_path):
    module = torch.nn.Sequential(torch.nn.Linear(5, 3), torch.nn.Tanh())
    with pytest.raises(AgentError, match="returns 3 values per observation"):
        load_agent(export_torchscript(module, tmp_path / "three.pt"))


def test_a_zip_that_is_not_torchscript(tmp_path):
    path = tmp_path / "notes.pt"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("notes.txt", "hello")
    with pytest.raises(AgentError, match="not TorchScript"):
        load_agent(path)


def test_missing_file_names_what_to_give():
    with pytest.raises(AgentError, match="no such agent file: nowhere.onnx"):
        load_agent("nowhere.onnx")


def test_missing_onnxruntime_names_the_install_command(onnx_actor, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # makes `import onnxruntime` fail
    with pytest.raises(AgentError, match=r"needs the 'onnxruntime' package: pip install onnx onnxruntime onnxscript"):
        load_agent(onnx_actor)


# --------------------------------------------------------------------------- failures while acting


def test_failures_while_acting_raise_agent_error():
    calls = []

    def flaky(obs):
        calls.append(1)
        if len(calls) > 2:  # the dry run makes two calls
            raise RuntimeError("CUDA out of memory")
        return np.zeros((len(obs), 2))

    agent = callable_agent(flaky, obs_dim=5)
    with pytest.raises(AgentError, match="the model raised RuntimeError: CUDA out of memory"):
        agent(OBS5)


@pytest.mark.parametrize("output, message", [
    (lambda obs: np.full((len(obs), 2), np.nan), "NaN"),
    (lambda obs: np.zeros((len(obs), 3)), "3 values per observation"),
    (lambda obs: np.zeros((len(obs), 2), dtype=np.int32), "not floating point"),
    (lambda obs: "left", "not floating point"),
])
def test_callable_contract_checked_at_creation(output, message):
    with pytest.raises(AgentError, match=message):
        callable_agent(output, obs_dim=5)


def test_observations_of_the_wrong_size_are_a_caller_error():
    with pytest.raises(ValueError, match=r"expects observations of shape \(batch, 5\)"):
        heuristic_agent()(np.zeros((1, 20), dtype=np.float32))


def test_onnx_agents_load_with_onnxruntimes_telemetry_off(onnx_actor, tmp_path):
    """onnxruntime >= 1.32 uploads telemetry and keeps an offline cache in ~/.cache unless told
    not to before it is imported; a student's laptop and the league's workers tell it."""
    probe = ("import os, sys\n"
             "from league.agents import load_agent\n"
             "agent = load_agent(sys.argv[1])\n"
             "print(os.environ['ORT_DISABLE_TELEMETRY'])\n")
    env = {"PATH": os.environ["PATH"], "HOME": str(tmp_path), "OMP_NUM_THREADS": "1",
           "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    result = subprocess.run([sys.executable, "-c", probe, str(onnx_actor)], capture_output=True, text=True,
                            env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split()[0] == "1"
    assert not (tmp_path / ".cache").exists()


def test_a_models_words_are_made_plain_before_anyone_shows_them():
    from league.agents import plain_text

    text = "bad\u202egnp.exe\nline two\x1b[31m \u200b" + "x" * 400
    cleaned = plain_text(text, limit=40)
    assert cleaned == "badgnp.exe line two[31m " + "x" * 13 + "..."
    assert all(ord(char) >= 32 for char in cleaned) and "\u202e" not in cleaned and len(cleaned) == 40

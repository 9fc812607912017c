"""Model validation in a sandbox (league/server/sandbox/validation.py): the static checks of
TorchScript uploads on their structure -- no code runs at load, and every method and hook is held to
the operator allow-list -- and the actions on the integrity report's probe set, computed at
validation and by the probe job's own sandbox (a model that fails on the set is still accepted).
The ONNX checks on their own: tests/validation/test_checks.py."""
from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import pytest

from league import testing as mf
from league.agents import load_agent
from league.server.sandbox.validation import probe_model, validate_model
from league.validation.limits import SandboxLimits
from league.validation.probes import (
    observations_key, probe_actions_from_bytes, probe_key, probe_observations, secret_probe_observations,
)

LIMITS = SandboxLimits(load_cpu_s=60, max_restarts=0)  # the static checks
FAST = SandboxLimits(first_call_allowance_s=0.3, load_cpu_s=20, max_restarts=1)  # the probe set


# --------------------------------------------------------------------------- static checks


@pytest.mark.parametrize("spelling", sorted(mf.LOAD_HOOK_SPELLINGS))
def test_an_archive_that_runs_code_at_load_is_refused_however_it_is_written(tmp_path, spelling):
    target = Path(f"/tmp/league-loaded-{uuid.uuid4().hex}")  # where its __setstate__ would write
    model = mf.torchscript_runs_code_at_load(tmp_path / "hook.pt", spelling, target=str(target))
    report = validate_model(model, "torchscript", LIMITS)
    assert not report.ok
    assert report.error.startswith("the TorchScript code defines __getstate__, which runs while the file is loaded")
    assert not target.exists()


def test_a_forbidden_operator_beside_forward_is_refused(tmp_path):
    report = validate_model(mf.torchscript_forbidden_op_beside_forward(tmp_path / "side.pt"), "torchscript", LIMITS)
    assert not report.ok
    assert report.error == ("operator aten::from_file (in RecursiveScriptModule.peek) is not allowed in league "
                            "models (MLP/CNN operators only)")


def test_a_plain_scripted_policy_passes(torchscript_actor):
    report = validate_model(torchscript_actor, "torchscript", LIMITS)
    assert report.ok, report.error


def test_a_model_saved_for_cuda_is_validated_on_the_cpu_or_refused_naming_cuda(tmp_path):
    """(tests/test_agents_gpu.py: every way a GPU's model comes, and its actions)"""
    moved, _ = mf.torchscript_for_cuda(tmp_path / "moved.pt", "to-string")
    report = validate_model(moved, "torchscript", LIMITS)
    assert report.ok and report.obs_dim == 5, report.error
    out_of_reach, _ = mf.torchscript_for_cuda(tmp_path / "helper.pt", "in-a-function")
    report = validate_model(out_of_reach, "torchscript", LIMITS)
    assert not report.ok
    assert report.error.startswith("the model needs CUDA (a GPU) and the league runs models on the CPU: ")
    assert "model.cpu() before torch.jit.script" in report.error


# --------------------------------------------------------------------------- the probe set


def test_validation_records_the_actions_the_model_gives_on_the_probe_set(tmp_path):
    model = mf.torchscript_mlp(tmp_path / "mlp.pt", seed=5)
    report = validate_model(model, "torchscript", FAST)
    assert report.ok and report.probe.key == probe_key(5) and report.probe.error is None
    expected = load_agent(model)(probe_observations(5))
    np.testing.assert_allclose(probe_actions_from_bytes(report.probe.actions), expected, atol=1e-6)
    again, _ = probe_model(model, "torchscript", 5, FAST, name="mlp")  # the probe job's path: the same actions
    assert again == [report.probe]


def test_the_secret_probe_job_path_answers_each_secret_set_in_one_sandbox(tmp_path):
    model = mf.torchscript_mlp(tmp_path / "mlp.pt", seed=5)
    sets = tuple(secret_probe_observations({"seed": seed, "episodes": 3, "env_options": {}}, 5) for seed in (1, 2))
    probes, _ = probe_model(model, "torchscript", 5, FAST, name="mlp", secret_sets=sets)
    assert [p.key for p in probes] == [observations_key(obs) for obs in sets] and probe_key(5) not in probes
    for probe, obs in zip(probes, sets, strict=True):
        np.testing.assert_allclose(probe_actions_from_bytes(probe.actions), load_agent(model)(obs), atol=1e-6)


def test_a_model_that_fails_on_the_probe_set_is_accepted_without_actions(tmp_path):
    """It returns NaN when the road runs straight or right: the timed dry run sees none of that, the
    probe set does (its evaluation decides what it costs)."""
    report = validate_model(mf.onnx_nan_when_straight(tmp_path / "nan.onnx"), "onnx", FAST)
    assert report.ok and report.obs_dim == 5
    assert (report.probe.key, report.probe.actions) == (probe_key(5), None)
    assert "NaN" in report.probe.error and "no actions on the integrity report's probe set" in report.log

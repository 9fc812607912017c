"""Actions on the integrity report's probe set, computed in the sandbox: at validation, and by the
probe job's own sandbox; a model that fails on the set is still accepted."""
from __future__ import annotations

import numpy as np

from league import testing as mf
from league.agents import load_agent
from league.server.sandbox.validation import probe_model, validate_model
from league.validation.limits import SandboxLimits
from league.validation.probes import probe_actions_from_bytes, probe_key, probe_observations

FAST = SandboxLimits(first_call_allowance_s=0.3, load_cpu_s=20, max_restarts=1)


def test_validation_records_the_actions_the_model_gives_on_the_probe_set(tmp_path):
    model = mf.torchscript_mlp(tmp_path / "mlp.pt", seed=5)
    report = validate_model(model, "torchscript", FAST)
    assert report.ok and report.probe.key == probe_key(5) and report.probe.error is None
    expected = load_agent(model)(probe_observations(5))
    np.testing.assert_allclose(probe_actions_from_bytes(report.probe.actions), expected, atol=1e-6)
    again, _ = probe_model(model, "torchscript", 5, FAST, name="mlp")  # the probe job's path: the same actions
    assert again == report.probe


def test_a_model_that_fails_on_the_probe_set_is_accepted_without_actions(tmp_path):
    """It returns NaN when the road runs straight or right: the timed dry run sees none of that, the
    probe set does (its evaluation decides what it costs)."""
    report = validate_model(mf.onnx_nan_when_straight(tmp_path / "nan.onnx"), "onnx", FAST)
    assert report.ok and report.obs_dim == 5
    assert (report.probe.key, report.probe.actions) == (probe_key(5), None)
    assert "NaN" in report.probe.error and "no actions on the integrity report's probe set" in report.log

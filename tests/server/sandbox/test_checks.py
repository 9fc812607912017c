"""Static checks of TorchScript uploads, on their structure: no code runs at load, and every
method and hook is held to the operator allow-list (validated in a real sandbox)."""
from __future__ import annotations

import uuid
from pathlib import Path

import pytest

from league import testing as mf
from league.server.sandbox.validation import validate_model
from league.validation.limits import SandboxLimits

LIMITS = SandboxLimits(load_cpu_s=60, max_restarts=0)


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

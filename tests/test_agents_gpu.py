"""Models from GPUs (league.agents.onto_cpu): a TorchScript file saved on or for CUDA -- parameters
on the GPU, a device written in forward (`.to("cuda")`, `.cuda()`, `device="cuda"`, `self.device`),
a device a trace recorded -- is loaded onto the CPU with the actions of the same network there; a
device the loader cannot reach (in a function forward calls) is refused, naming CUDA and the fix.
The files are made without a GPU (league.testing.torchscript_for_cuda); the server's side:
tests/server/sandbox/test_validation.py."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from league import testing as mf
from league.agents import AgentError, load_agent
from league.exit_codes import EXIT_OK
from league.validation.loading import load_checked

torch = pytest.importorskip("torch")

LOADED = [how for how in mf.GPU_EXPORTS if how != "in-a-function"]


def observations() -> np.ndarray:
    return np.random.default_rng(3).uniform(-1, 1, (16, 5)).astype(np.float32)


@pytest.mark.parametrize("how", LOADED)
def test_a_model_saved_for_cuda_runs_on_the_cpu_with_the_networks_actions(tmp_path, how):
    path, plain = mf.torchscript_for_cuda(tmp_path / f"{how}.pt", how)
    with pytest.raises((RuntimeError, NotImplementedError)):  # as saved, it needs a GPU
        torch.jit.load(str(path), map_location=None if how == "parameters" else "cpu")(torch.zeros(2, 5))
    with torch.no_grad():
        expected = plain(torch.from_numpy(observations())).numpy()
    for agent in (load_agent(path), load_checked(path, memory_mb=None)):  # `league evaluate`'s, the check's
        assert agent.obs_dim == 5
        np.testing.assert_array_equal(agent(observations()), expected)


def test_a_device_out_of_the_loaders_reach_is_refused_naming_cuda_and_the_fix(tmp_path):
    path, _ = mf.torchscript_for_cuda(tmp_path / "policy.pt", "in-a-function")
    for load in (load_agent, lambda p: load_checked(p, memory_mb=None)):
        with pytest.raises(AgentError) as refused:
            load(path)
        assert refused.value.reason.startswith("the model needs CUDA (a GPU) and the league runs models on the CPU: "
                                               "InAFunction.forward names the device cuda; export it from the CPU: "
                                               "model.cpu() before torch.jit.script")


def test_league_check_says_what_a_gpu_model_needs(tmp_path):
    loaded, _ = mf.torchscript_for_cuda(tmp_path / "moved.pt", "cuda-call")
    refused, _ = mf.torchscript_for_cuda(tmp_path / "policy.pt", "in-a-function")
    done = subprocess.run([sys.executable, "-m", "league.cli", "check", str(loaded), str(refused)],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert done.returncode != EXIT_OK
    first, second = done.stdout.splitlines()
    assert first.startswith("moved.pt: the server would accept it: observation size 5")
    assert second.startswith("policy.pt: the server would reject it: the model needs CUDA (a GPU)")
    assert "model.cpu()" in second and "wrong input size" not in done.stdout

"""Models for the toolkit's tests and benchmarks, built in code (nothing binary is checked in).

`thesis_driver()` is a thesis-size actor (5 -> 64 -> 64 -> 2, ReLU, tanh output, as DDPG2/TD3's)
whose weights are wired to drive like SPEC's heuristic, so its episodes are full laps rather
than crashes after a few steps; the other units carry small random weights so that inference
costs what a trained actor's does. The `onnx_*` builders write the broken models that
`load_agent` must reject with a clear reason.
"""
from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np

HIDDEN = 64
TARGET_SPEED = 0.25


def thesis_driver(obs_dim: int = 5, seed: int = 0, target_speed: float = TARGET_SPEED):
    """A torch MLP 5 -> 64 -> 64 -> 2 that steers toward the free direction and holds `target_speed`."""
    import torch

    torch.manual_seed(seed)
    net = torch.nn.Sequential(
        torch.nn.Linear(obs_dim, HIDDEN), torch.nn.ReLU(),
        torch.nn.Linear(HIDDEN, HIDDEN), torch.nn.ReLU(),
        torch.nn.Linear(HIDDEN, 2), torch.nn.Tanh(),
    )
    first, second, out = net[0], net[2], net[4]
    direction, speed = 0, obs_dim - 1
    with torch.no_grad():
        for layer in (first, second, out):
            layer.weight.mul_(0.05)
            layer.bias.zero_()
        # hidden units 0..3: relu(direction), relu(-direction), relu(target - speed), relu(speed - target)
        first.weight[:4] = 0.0
        first.weight[0, direction], first.weight[1, direction] = 1.0, -1.0
        first.weight[2, speed], first.bias[2] = -1.0, target_speed
        first.weight[3, speed], first.bias[3] = 1.0, -target_speed
        second.weight[:4] = 0.0
        second.weight[:4, :4] = torch.eye(4)  # pass the four features through
        out.weight[:] = 0.0
        out.weight[0, 2], out.weight[0, 3] = 40.0, -40.0  # throttle: full below the target, brake above
        out.weight[1, 0], out.weight[1, 1] = -1.0 / (math.pi / 6), 1.0 / (math.pi / 6)  # turn ~ -direction/(pi/6)
    return net.eval()


class TwoHeads:
    """Wraps a module so that it returns (actions, value), as some thesis actors do."""

    def __new__(cls, module):
        import torch

        class _TwoHeads(torch.nn.Module):
            def __init__(self, inner):
                super().__init__()
                self.inner = inner

            def forward(self, obs):
                actions = self.inner(obs)
                return actions, actions.sum(dim=1, keepdim=True)

        return _TwoHeads(module).eval()


def _save_graph(path: Path, nodes, inputs, outputs, initializers=()) -> Path:
    import onnx
    from onnx import helper

    graph = helper.make_graph(nodes, "test_model", inputs, outputs, list(initializers))
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return path


def _linear_onnx(path: Path, in_size: int, out_size: int, out_type: str = "float", fill: float | None = None) -> Path:
    """obs (batch, in_size) @ W (in_size, out_size); optional constant fill (e.g. NaN) and Cast."""
    from onnx import TensorProto, helper, numpy_helper

    weights = np.full((in_size, out_size), 0.1 if fill is None else fill, dtype=np.float32)
    nodes = [helper.make_node("MatMul", ["obs", "W"], ["y" if out_type != "float" else "actions"])]
    elem = TensorProto.FLOAT
    if out_type == "int64":
        nodes.append(helper.make_node("Cast", ["y"], ["actions"], to=TensorProto.INT64))
        elem = TensorProto.INT64
    inputs = [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", in_size])]
    outputs = [helper.make_tensor_value_info("actions", elem, ["batch", out_size])]
    return _save_graph(path, nodes, inputs, outputs, [numpy_helper.from_array(weights, "W")])


def onnx_wrong_input(path: Path) -> Path:
    return _linear_onnx(path, 7, 2)


def onnx_three_outputs(path: Path) -> Path:
    return _linear_onnx(path, 5, 3)


def onnx_nan_outputs(path: Path) -> Path:
    return _linear_onnx(path, 5, 2, fill=float("nan"))


def onnx_integer_outputs(path: Path) -> Path:
    return _linear_onnx(path, 5, 2, out_type="int64")


def pickle_renamed_pt(path: Path) -> Path:
    path.write_bytes(pickle.dumps({"actor": [0.1, 0.2]}))
    return path


def truncated_copy(source: Path, path: Path) -> Path:
    data = source.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


class BatchOfOne:
    """Wraps a module so that it only takes one observation, as many students' exports do:
    ``reshape`` the input to (1, obs_dim) (a batch of 2 is an error)."""

    def __new__(cls, module, obs_dim: int = 5):
        import torch

        class _BatchOfOne(torch.nn.Module):
            def __init__(self, inner):
                super().__init__()
                self.inner = inner

            def forward(self, obs):
                return self.inner(obs.reshape(1, obs_dim))

        return _BatchOfOne(module).eval()

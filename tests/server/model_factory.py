"""Model files for the server tests and benchmark: good agents and every kind of bad upload.

Each function writes one file and returns its path. Built with the onnx helper API and
torch.jit, deterministically (fixed seeds), so tests never depend on downloaded models.
"""
from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from league.agents import export_heuristic_onnx

OPSET = [helper.make_opsetid("", 17)]


def _save(graph, path: Path, opsets=OPSET) -> Path:
    model = helper.make_model(graph, opset_imports=opsets, producer_name="league-tests")
    model.ir_version = 8
    onnx.save(model, str(path))
    return path


def _dense(rng: np.random.Generator, name: str, fan_in: int, fan_out: int) -> list:
    weight = rng.normal(0, 1 / math.sqrt(fan_in), (fan_in, fan_out)).astype(np.float32)
    bias = np.zeros(fan_out, dtype=np.float32)
    return [numpy_helper.from_array(weight, f"{name}_w"), numpy_helper.from_array(bias, f"{name}_b")]


def onnx_mlp(path: Path, in_dim: int = 5, out_dim: int = 2, hidden: tuple[int, ...] = (64, 64), seed: int = 0,
             nan: bool = False) -> Path:
    """A tanh MLP policy (batch, in_dim) -> (batch, out_dim); with `nan`, its outputs are NaN."""
    rng = np.random.default_rng(seed)
    sizes = [in_dim, *hidden, out_dim]
    nodes, initializers, current = [], [], "obs"
    for i, (fan_in, fan_out) in enumerate(zip(sizes[:-1], sizes[1:])):
        initializers += _dense(rng, f"l{i}", fan_in, fan_out)
        nodes.append(helper.make_node("Gemm", [current, f"l{i}_w", f"l{i}_b"], [f"h{i}"]))
        activation = "Tanh" if i == len(sizes) - 2 else "Relu"
        nodes.append(helper.make_node(activation, [f"h{i}"], [f"a{i}"]))
        current = f"a{i}"
    if nan:
        initializers.append(numpy_helper.from_array(np.array(np.nan, dtype=np.float32), "nan"))
        nodes.append(helper.make_node("Mul", [current, "nan"], ["poisoned"]))
        current = "poisoned"
    nodes.append(helper.make_node("Identity", [current], ["actions"]))
    graph = helper.make_graph(nodes, "mlp",
                              [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", in_dim])],
                              [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", out_dim])],
                              initializers)
    return _save(graph, path)


def onnx_heuristic(path: Path) -> Path:
    """The toolkit's heuristic driver as ONNX: a good agent that completes most laps."""
    return export_heuristic_onnx(path)


def onnx_external_data(path: Path) -> Path:
    """An MLP whose weights live in a side file (refused: only self-contained files are accepted)."""
    onnx_mlp(path)
    model = onnx.load(str(path))
    onnx.save(model, str(path), save_as_external_data=True, all_tensors_to_one_file=True,
              location="weights.bin", size_threshold=0)
    return path


def onnx_memory_hog(path: Path, elements: int = 1 << 31) -> Path:
    """Expands the observation to `elements` floats (8 GB by default) before answering."""
    nodes = [
        helper.make_node("Expand", ["one", "huge_shape"], ["huge"]),
        helper.make_node("ReduceSum", ["huge"], ["total"], keepdims=0),
        helper.make_node("Slice", ["obs", "starts", "ends", "axes"], ["two"]),
        helper.make_node("Add", ["two", "total"], ["actions"]),
    ]
    initializers = [numpy_helper.from_array(np.ones(1, np.float32), "one"),
                    numpy_helper.from_array(np.array([elements], np.int64), "huge_shape"),
                    numpy_helper.from_array(np.array([0], np.int64), "starts"),
                    numpy_helper.from_array(np.array([2], np.int64), "ends"),
                    numpy_helper.from_array(np.array([1], np.int64), "axes")]
    graph = helper.make_graph(nodes, "hog", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])],
                              [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", 2])], initializers)
    return _save(graph, path)


def onnx_slow(path: Path, width: int = 1024, layers: int = 600) -> Path:
    """A chain of `layers` width x width MatMuls sharing one weight (a small file, a slow model: ~50 ms of
    CPU per observation against the 20 ms allowed, and few enough nodes that loading it stays well
    inside the tests' 8 s load budget on a busy machine, where 1500 layers took 2.6 s to load alone)."""
    rng = np.random.default_rng(1)
    def weight(name: str, shape: tuple[int, int]):
        return numpy_helper.from_array(rng.normal(0, 1 / math.sqrt(width), shape).astype(np.float32), name)

    initializers = [weight("w_in", (5, width)), weight("w", (width, width)), weight("w_out", (width, 2))]
    nodes, current = [helper.make_node("MatMul", ["obs", "w_in"], ["h_in"])], "h_in"
    for i in range(layers):
        nodes.append(helper.make_node("MatMul", [current, "w"], [f"h{i}"]))
        current = f"h{i}"
    nodes += [helper.make_node("MatMul", [current, "w_out"], ["raw"]), helper.make_node("Tanh", ["raw"], ["actions"])]
    graph = helper.make_graph(nodes, "slow", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])],
                              [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", 2])], initializers)
    return _save(graph, path)


def onnx_custom_domain(path: Path) -> Path:
    """Uses an operator of a non-standard domain (a custom-op library would be needed to run it)."""
    node = helper.make_node("Evil", ["obs"], ["actions"], domain="com.example")
    graph = helper.make_graph([node], "custom", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", 5])],
                              [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", 2])])
    return _save(graph, path, OPSET + [helper.make_opsetid("com.example", 1)])


def random_bytes(path: Path, size: int = 4096, seed: int = 0) -> Path:
    path.write_bytes(np.random.default_rng(seed).bytes(size))
    return path


def truncated(source: Path, path: Path) -> Path:
    data = source.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def pickle_renamed_pt(path: Path) -> Path:
    """A pickle (what torch.save writes inside, and what runs code on load) under a .pt name."""
    path.write_bytes(pickle.dumps({"state_dict": {"weight": [1.0, 2.0]}}, protocol=4))
    return path


# --------------------------------------------------------------------------- TorchScript


def _torch():
    import torch

    return torch


def torchscript_heuristic(path: Path) -> Path:
    """The heuristic driver as a scripted torch module (a good TorchScript agent)."""
    torch = _torch()

    class HeuristicDriver(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            direction, speed = obs[:, 0:1], obs[:, 4:5]
            acc = torch.where(speed < 0.25, torch.full_like(speed, 0.5), torch.full_like(speed, -0.2))
            turn = torch.clamp(direction / (-math.pi / 6), -1.0, 1.0)
            return torch.cat([acc, turn], dim=1)

    torch.jit.script(HeuristicDriver()).save(str(path))
    return path


def torchscript_mlp(path: Path, in_dim: int = 5, seed: int = 0) -> Path:
    torch = _torch()
    torch.manual_seed(seed)
    net = torch.nn.Sequential(torch.nn.Linear(in_dim, 64), torch.nn.ReLU(), torch.nn.Linear(64, 2), torch.nn.Tanh())
    torch.jit.script(net).save(str(path))
    return path


def onnx_fixed_batch(module, path: Path, obs_dim: int = 5) -> Path:
    """A torch policy exported to ONNX without a dynamic batch axis: input (1, obs_dim), one
    observation at a time, as many students' exports are."""
    import warnings

    torch = _torch()
    module.eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (torch.zeros(1, obs_dim),), str(path), input_names=["obs"], output_names=["actions"],
                          opset_version=17, dynamo=False)
    return path


def torchscript_fixed_batch(module, path: Path, obs_dim: int = 5) -> Path:
    """A torch policy traced for one observation at a time (tests.toolkit_models.BatchOfOne wraps
    it): a batch of 2 is an error, as in many students' exports."""
    from tests.toolkit_models import BatchOfOne

    import warnings

    torch = _torch()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.jit.trace(BatchOfOne(module.eval(), obs_dim), torch.zeros(1, obs_dim)).save(str(path))
    return path


def torchscript_loop(path: Path, iterations: int = 10_000_000) -> Path:
    """Loops `iterations` times per call: past any deadline with the default count."""
    torch = _torch()

    class Looper(torch.nn.Module):
        def __init__(self, n: int):
            super().__init__()
            self.n = n

        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            x = obs[:, 0:2]
            for _ in range(self.n):
                x = x * 1.0000001
            return torch.tanh(x)

    torch.jit.script(Looper(iterations)).save(str(path))
    return path


def torchscript_reads_file(path: Path) -> Path:
    """Reads /etc/passwd with aten::from_file (refused by the operator allow-list)."""
    torch = _torch()

    class Reader(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            data = torch.from_file("/etc/passwd", size=16, dtype=torch.uint8)
            return obs[:, 0:2] * 0.0 + data.float().sum() * 0.0

    torch.jit.script(Reader()).save(str(path))
    return path


LOAD_HOOK_SPELLINGS = {  # how "def __setstate__(" may be written in an archive's code, all the same to Python
    "plain": "def __setstate__(",
    "two spaces": "def  __setstate__(",
    "tab": "def\t__setstate__(",
    "space before parenthesis": "def __setstate__ (",
    "line continuation": "def \\\n    __setstate__(",
}


def torchscript_runs_code_at_load(path: Path, spelling: str = "plain", target: str = "/tmp/league-loaded") -> Path:
    """A loadable module whose __setstate__ (run by torch.jit.load) maps a file of its own choosing
    with aten::from_file, written in the archive's code as LOAD_HOOK_SPELLINGS[spelling]."""
    torch = _torch()

    class LoadTimeWriter(torch.nn.Module):
        def __init__(self, target: str):
            super().__init__()
            self.target = target

        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return torch.tanh(obs[:, 0:2])

        @torch.jit.export
        def __getstate__(self) -> tuple[str, bool]:
            return (self.target, self.training)

        @torch.jit.export
        def __setstate__(self, state: tuple[str, bool]) -> None:
            self.target = state[0]
            mapped = torch.from_file(self.target, shared=True, size=1, dtype=torch.uint8)  # creates the file
            self.training = state[1] or bool(mapped[0] > 1)  # used, so the compiler keeps the call

    torch.jit.script(LoadTimeWriter(target)).save(str(path))
    return _respell(path, "def __setstate__(", LOAD_HOOK_SPELLINGS[spelling])


def _respell(path: Path, old: str, new: str) -> Path:
    """Rewrite the archive's code files, keeping every other entry as it is."""
    import zipfile

    entries = []
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            data = archive.read(info)
            if info.filename.endswith(".py") and old.encode() in data:
                data = data.replace(old.encode(), new.encode())
            entries.append((info, data))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        for info, data in entries:
            archive.writestr(info, data)
    return path


def torchscript_forbidden_op_beside_forward(path: Path) -> Path:
    """forward is plain; an exported method reads /etc/passwd (aten::from_file)."""
    torch = _torch()

    class SideReader(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return torch.tanh(obs[:, 0:2])

        @torch.jit.export
        def peek(self) -> torch.Tensor:
            return torch.from_file("/etc/passwd", size=16, dtype=torch.uint8)

    torch.jit.script(SideReader()).save(str(path))
    return path


def torchscript_memory_hog(path: Path) -> Path:
    torch = _torch()

    class Hog(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            huge = torch.ones(1 << 31)
            return obs[:, 0:2] * huge[0]

    torch.jit.script(Hog()).save(str(path))
    return path


def onnx_nan_when_straight(path: Path, threshold: float = 0.001) -> Path:
    """The heuristic driver, poisoned: it returns NaN once the best direction (observation[0])
    is <= `threshold`, i.e. straight ahead or to the right.

    actions = heuristic(obs) + sqrt(obs[:, 0:1] - threshold) * 0: validation's dry runs look a
    little to the left (direction 0.025-0.075) and see good actions, so the model is accepted;
    in a race the road soon runs straight or turns right and the car is out (a DNF).
    """
    export_heuristic_onnx(path)
    model = onnx.load(str(path))
    graph = model.graph
    for node in graph.node:  # the heuristic's last node now writes "good_actions"
        node.output[:] = ["good_actions" if name == "actions" else name for name in node.output]
    graph.node.extend([
        helper.make_node("Slice", ["obs", "nan_starts", "nan_ends", "nan_axes"], ["nan_direction"]),
        helper.make_node("Sub", ["nan_direction", "nan_threshold"], ["nan_shifted"]),
        helper.make_node("Sqrt", ["nan_shifted"], ["nan_root"]),  # NaN when direction < threshold
        helper.make_node("Mul", ["nan_root", "nan_zero"], ["nan_poison"]),  # 0 or NaN
        helper.make_node("Add", ["good_actions", "nan_poison"], ["actions"]),
    ])
    graph.initializer.extend([
        numpy_helper.from_array(np.array([0], np.int64), "nan_starts"),
        numpy_helper.from_array(np.array([1], np.int64), "nan_ends"),
        numpy_helper.from_array(np.array([1], np.int64), "nan_axes"),
        numpy_helper.from_array(np.array(threshold, np.float32), "nan_threshold"),
        numpy_helper.from_array(np.array(0.0, np.float32), "nan_zero"),
    ])
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


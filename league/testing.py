"""Model files for tests and benchmarks, built in code: good agents and every kind of bad upload.

Shipped with the package (as `numpy.testing` is) so that the benchmarks and the tests share one
set of builders without importing each other. Importing this module is cheap: torch and onnx are
imported inside the functions that need them, and nothing here imports `league.server`.

- `thesis_driver()` is a thesis-size actor (5 -> 64 -> 64 -> 2, ReLU, tanh output, as DDPG2/TD3's)
  whose weights are wired to drive like SPEC's heuristic, so its episodes are full laps rather than
  crashes after a few steps; the other units carry small random weights so that inference costs
  what a trained actor's does. `TwoHeads` and `BatchOfOne` wrap a module as some students' exports do.
- The `onnx_*` and `torchscript_*` functions write one file each and return its path:
  deterministic (fixed seeds), so no test depends on a downloaded model. The hostile ones (memory
  hogs, slow or looping models, file readers, code run at load) are what the sandbox must refuse.
"""
from __future__ import annotations

import itertools
import math
import pickle
import warnings
import zipfile
from pathlib import Path
from collections.abc import Callable
from typing import Any

import numpy as np

HIDDEN = 64  # units of each hidden layer of the thesis' actors
TARGET_SPEED = 0.25  # the heuristic driver's speed
OPSET = 17  # the ONNX default domain's version of every graph built here

LOAD_HOOK_SPELLINGS = {  # how "def __setstate__(" may be written in an archive's code, all the same to Python
    "plain": "def __setstate__(",
    "two spaces": "def  __setstate__(",
    "tab": "def\t__setstate__(",
    "space before parenthesis": "def __setstate__ (",
    "line continuation": "def \\\n    __setstate__(",
}


# --------------------------------------------------------------------------- torch modules


def thesis_driver(obs_dim: int = 5, seed: int = 0, target_speed: float = TARGET_SPEED):
    """A torch MLP obs_dim -> 64 -> 64 -> 2 that steers toward the free direction and holds `target_speed`."""
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


# --------------------------------------------------------------------------- ONNX


def _save(graph, path: Path, domains: tuple[tuple[str, int], ...] = ()) -> Path:
    import onnx
    from onnx import helper

    opsets = [helper.make_opsetid("", OPSET)] + [helper.make_opsetid(domain, version) for domain, version in domains]
    model = helper.make_model(graph, opset_imports=opsets, producer_name="league-testing")
    model.ir_version = 8
    onnx.save(model, str(path))
    return path


def _graph(nodes: list, name: str, initializers: list = (), in_dim: int = 5, out_dim: int = 2, out_type: int = 1):
    """A graph with the toolkit's interface: input "obs" (batch, in_dim) of floats, output "actions"
    (batch, out_dim) of `out_type` (an onnx.TensorProto element type; 1 is FLOAT)."""
    from onnx import TensorProto, helper

    return helper.make_graph(nodes, name, [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", in_dim])],
                             [helper.make_tensor_value_info("actions", out_type, ["batch", out_dim])],
                             list(initializers))


def onnx_mlp(path: Path, in_dim: int = 5, out_dim: int = 2, hidden: tuple[int, ...] = (HIDDEN, HIDDEN), seed: int = 0,
             nan: bool = False, integer: bool = False) -> Path:
    """A tanh MLP policy (batch, in_dim) -> (batch, out_dim); with `nan`, its outputs are NaN; with
    `integer`, they are cast to int64."""
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(seed)
    sizes = [in_dim, *hidden, out_dim]
    nodes, initializers, current = [], [], "obs"
    for i, (fan_in, fan_out) in enumerate(itertools.pairwise(sizes)):
        weight = rng.normal(0, 1 / math.sqrt(fan_in), (fan_in, fan_out)).astype(np.float32)
        initializers += [numpy_helper.from_array(weight, f"l{i}_w"),
                         numpy_helper.from_array(np.zeros(fan_out, np.float32), f"l{i}_b")]
        nodes.append(helper.make_node("Gemm", [current, f"l{i}_w", f"l{i}_b"], [f"h{i}"]))
        nodes.append(helper.make_node("Tanh" if i == len(sizes) - 2 else "Relu", [f"h{i}"], [f"a{i}"]))
        current = f"a{i}"
    if nan:
        initializers.append(numpy_helper.from_array(np.array(np.nan, dtype=np.float32), "nan"))
        nodes.append(helper.make_node("Mul", [current, "nan"], ["poisoned"]))
        current = "poisoned"
    if integer:
        nodes.append(helper.make_node("Cast", [current], ["actions"], to=TensorProto.INT64))
    else:
        nodes.append(helper.make_node("Identity", [current], ["actions"]))
    kind = TensorProto.INT64 if integer else TensorProto.FLOAT
    return _save(_graph(nodes, "mlp", initializers, in_dim, out_dim, kind), path)


def onnx_heuristic(path: Path) -> Path:
    """The toolkit's heuristic driver as ONNX: a good agent that completes most laps."""
    from league.agents import export_heuristic_onnx

    return export_heuristic_onnx(path)


def onnx_fixed_batch(module, path: Path, obs_dim: int = 5) -> Path:
    """A torch policy exported to ONNX without a dynamic batch axis: input (1, obs_dim), one
    observation at a time, as many students' exports are."""
    import torch

    module.eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, (torch.zeros(1, obs_dim),), str(path), input_names=["obs"], output_names=["actions"],
                          opset_version=OPSET, dynamo=False)
    return path


def onnx_external_data(path: Path) -> Path:
    """An MLP whose weights live in a side file (refused: only self-contained files are accepted)."""
    import onnx

    onnx_mlp(path)
    model = onnx.load(str(path))
    onnx.save(model, str(path), save_as_external_data=True, all_tensors_to_one_file=True,
              location="weights.bin", size_threshold=0)
    return path


def onnx_memory_hog(path: Path, elements: int = 1 << 31) -> Path:
    """Expands the observation to `elements` floats (8 GB by default) before answering."""
    from onnx import helper, numpy_helper

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
    return _save(_graph(nodes, "hog", initializers), path)


def onnx_slow(path: Path, width: int = 1024, layers: int = 600) -> Path:
    """A chain of `layers` width x width MatMuls sharing one weight (a small file, a slow model: ~50 ms of
    CPU per observation against the 20 ms allowed, and few enough nodes that loading it stays well
    inside the tests' 8 s load budget on a busy machine, where 1500 layers took 2.6 s to load alone)."""
    from onnx import helper, numpy_helper

    rng = np.random.default_rng(1)

    def weight(name: str, shape: tuple[int, int]):
        return numpy_helper.from_array(rng.normal(0, 1 / math.sqrt(width), shape).astype(np.float32), name)

    initializers = [weight("w_in", (5, width)), weight("w", (width, width)), weight("w_out", (width, 2))]
    nodes, current = [helper.make_node("MatMul", ["obs", "w_in"], ["h_in"])], "h_in"
    for i in range(layers):
        nodes.append(helper.make_node("MatMul", [current, "w"], [f"h{i}"]))
        current = f"h{i}"
    nodes += [helper.make_node("MatMul", [current, "w_out"], ["raw"]), helper.make_node("Tanh", ["raw"], ["actions"])]
    return _save(_graph(nodes, "slow", initializers), path)


def onnx_custom_domain(path: Path) -> Path:
    """Uses an operator of a non-standard domain (a custom-op library would be needed to run it)."""
    from onnx import helper

    node = helper.make_node("Evil", ["obs"], ["actions"], domain="com.example")
    return _save(_graph([node], "custom"), path, domains=(("com.example", 1),))


def onnx_nan_when_straight(path: Path, threshold: float = 0.001) -> Path:
    """The heuristic driver, poisoned: it returns NaN once the best direction (observation[0])
    is <= `threshold`, i.e. straight ahead or to the right.

    actions = heuristic(obs) + sqrt(obs[:, 0:1] - threshold) * 0: validation's dry runs look a
    little to the left (direction 0.025-0.075) and see good actions, so the model is accepted;
    in a race the road soon runs straight or turns right and the car is out (a DNF).
    """
    import onnx
    from onnx import helper, numpy_helper

    onnx_heuristic(path)
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


# --------------------------------------------------------------------------- not a model


def random_bytes(path: Path, size: int = 4096, seed: int = 0) -> Path:
    path.write_bytes(np.random.default_rng(seed).bytes(size))
    return path


def truncated(source: Path, path: Path) -> Path:
    """The first half of `source`'s bytes."""
    data = source.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def pickle_renamed_pt(path: Path) -> Path:
    """A pickle (what torch.save writes inside, and what runs code on load) under a .pt name."""
    path.write_bytes(pickle.dumps({"state_dict": {"weight": [1.0, 2.0]}}, protocol=4))
    return path


# --------------------------------------------------------------------------- TorchScript


def torchscript_mlp(path: Path, in_dim: int = 5, seed: int = 0) -> Path:
    import torch

    torch.manual_seed(seed)
    net = torch.nn.Sequential(torch.nn.Linear(in_dim, HIDDEN), torch.nn.ReLU(), torch.nn.Linear(HIDDEN, 2),
                              torch.nn.Tanh())
    torch.jit.script(net).save(str(path))
    return path


def torchscript_raises_when_close(path: Path, distance: float = 0.05) -> Path:
    """The thesis driver, scripted, raising when a batch holds an observation with something closer
    ahead than `distance` (observation[2]): a model that fails on some observations only."""
    import torch

    class RaisesWhenClose(torch.nn.Module):
        def __init__(self, driver: torch.nn.Module, distance: float):
            super().__init__()
            self.driver, self.distance = driver, distance

        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            if bool(obs[:, 2].min() < self.distance):
                raise RuntimeError("too close to a wall")
            return self.driver(obs)

    torch.jit.script(RaisesWhenClose(thesis_driver(), distance)).save(str(path))
    return path


def torchscript_fixed_batch(module, path: Path, obs_dim: int = 5) -> Path:
    """A torch policy traced for one observation at a time (wrapped in `BatchOfOne`): a batch of 2
    is an error, as in many students' exports."""
    import torch

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.jit.trace(BatchOfOne(module.eval(), obs_dim), torch.zeros(1, obs_dim)).save(str(path))
    return path


def torchscript_loop(path: Path, iterations: int = 10_000_000) -> Path:
    """Loops `iterations` times per call: past any deadline with the default count."""
    import torch

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
    import torch

    class Reader(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            data = torch.from_file("/etc/passwd", size=16, dtype=torch.uint8)
            return obs[:, 0:2] * 0.0 + data.float().sum() * 0.0

    torch.jit.script(Reader()).save(str(path))
    return path


def torchscript_runs_code_at_load(path: Path, spelling: str = "plain", target: str = "/tmp/league-loaded") -> Path:
    """A loadable module whose __setstate__ (run by torch.jit.load) maps a file of its own choosing
    with aten::from_file, written in the archive's code as LOAD_HOOK_SPELLINGS[spelling]."""
    import torch

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
    import torch

    class SideReader(torch.nn.Module):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return torch.tanh(obs[:, 0:2])

        @torch.jit.export
        def peek(self) -> torch.Tensor:
            return torch.from_file("/etc/passwd", size=16, dtype=torch.uint8)

    torch.jit.script(SideReader()).save(str(path))
    return path



# --------------------------------------------------------------------------- disguised copies (integrity report)
# Each takes a feed-forward ONNX policy (the bundled baselines': Sub/Div normalisation, Gemm, Tanh/Relu) and writes
# a copy a student might upload to dodge the integrity report; tests/server/test_integrity_variants.py checks that
# each is still reported as a copy of what it came from.


def _last_node(model, op_type: str):
    return [node for node in model.graph.node if node.op_type == op_type][-1]


def _append_output_nodes(model, nodes: list, initializers: list, new_output: str) -> None:
    """Rename the graph's output, append nodes that read it, and make `new_output` the output again."""
    old = model.graph.output[0].name
    for node in model.graph.node:
        node.output[:] = [f"{old}_inner" if name == old else name for name in node.output]
        node.input[:] = [f"{old}_inner" if name == old else name for name in node.input]
    for node in nodes:
        node.input[:] = [f"{old}_inner" if name == old else name for name in node.input]
        node.output[:] = [old if name == new_output else name for name in node.output]
    model.graph.node.extend(nodes)
    model.graph.initializer.extend(initializers)


def onnx_scaled_last_layer(source: Path, path: Path, factor: float = 1.03) -> Path:
    """The last Gemm's weights and bias times `factor` (before the output's tanh: not an affine change)."""
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(source))
    last = _last_node(model, "Gemm")
    for tensor in model.graph.initializer:
        if tensor.name in last.input[1:]:
            tensor.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(tensor) * np.float32(factor), tensor.name))
    onnx.save(model, str(path))
    return path


def onnx_scaled_outputs(source: Path, path: Path, factor: float = 0.98, offset: float = 0.0) -> Path:
    """The actions times `factor`, plus `offset`."""
    import onnx
    from onnx import helper, numpy_helper

    model = onnx.load(str(source))
    constants = [numpy_helper.from_array(np.float32(factor), "copy_factor"),
                 numpy_helper.from_array(np.float32(offset), "copy_offset")]
    nodes = [helper.make_node("Mul", [model.graph.output[0].name, "copy_factor"], ["copy_scaled"]),
             helper.make_node("Add", ["copy_scaled", "copy_offset"], ["copy_out"])]
    _append_output_nodes(model, nodes, constants, "copy_out")
    onnx.save(model, str(path))
    return path


def onnx_weight_noise(source: Path, path: Path, std: float = 1e-6, seed: int = 0) -> Path:
    """Every weight plus N(0, std)."""
    import onnx
    from onnx import numpy_helper

    rng = np.random.default_rng(seed)
    model = onnx.load(str(source))
    for tensor in model.graph.initializer:
        values = numpy_helper.to_array(tensor)
        if values.dtype == np.float32:
            noisy = values + rng.normal(0, std, values.shape).astype(np.float32)
            tensor.CopyFrom(numpy_helper.from_array(noisy, tensor.name))
    onnx.save(model, str(path))
    return path


def onnx_extra_identity_layer(source: Path, path: Path) -> Path:
    """An extra linear layer (identity weights, zero bias) after the output: another file, other nodes."""
    import onnx
    from onnx import helper, numpy_helper

    model = onnx.load(str(source))
    width = model.graph.output[0].type.tensor_type.shape.dim[1].dim_value
    constants = [numpy_helper.from_array(np.eye(width, dtype=np.float32), "copy_eye"),
                 numpy_helper.from_array(np.zeros(width, np.float32), "copy_zero")]
    nodes = [helper.make_node("Gemm", [model.graph.output[0].name, "copy_eye", "copy_zero"], ["copy_out"])]
    _append_output_nodes(model, nodes, constants, "copy_out")
    onnx.save(model, str(path))
    return path


def onnx_probe_aware(source: Path, path: Path, probes: np.ndarray, radius: float = 1e-4, seed: int = 0) -> Path:
    """Answers like `source` except within `radius` (every value) of one of `probes`, where it adds a
    shift of its own to each probe (uniform in [-0.9, 0.9]): a copy that looks like another policy on
    a probe set it knows in advance, and is `source` everywhere else."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    model = onnx.load(str(source))
    probes = np.asarray(probes, np.float32)
    shifts = np.random.default_rng(seed).uniform(-0.9, 0.9, (len(probes), 2)).astype(np.float32)
    constants = [numpy_helper.from_array(probes[None], "copy_probes"),  # (1, P, D)
                 numpy_helper.from_array(np.array([1], np.int64), "copy_axis1"),
                 numpy_helper.from_array(np.float32(radius), "copy_radius"),
                 numpy_helper.from_array(shifts, "copy_shifts")]  # (P, 2)
    nodes = [helper.make_node("Unsqueeze", ["obs", "copy_axis1"], ["copy_obs3"]),  # (B, 1, D)
             helper.make_node("Sub", ["copy_obs3", "copy_probes"], ["copy_diff"]),  # (B, P, D)
             helper.make_node("Abs", ["copy_diff"], ["copy_abs"]),
             helper.make_node("ReduceMax", ["copy_abs"], ["copy_far"], axes=[2], keepdims=0),  # (B, P)
             helper.make_node("Less", ["copy_far", "copy_radius"], ["copy_near"]),  # (B, P): at that probe
             helper.make_node("Cast", ["copy_near"], ["copy_nearf"], to=TensorProto.FLOAT),
             helper.make_node("MatMul", ["copy_nearf", "copy_shifts"], ["copy_delta"]),  # (B, 2)
             helper.make_node("Add", [model.graph.output[0].name, "copy_delta"], ["copy_out"])]
    _append_output_nodes(model, nodes, constants, "copy_out")
    onnx.save(model, str(path))
    return path


def torchscript_from_onnx(source: Path, path: Path) -> Path:
    """The same weights as a torch module saved as TorchScript (traced), for a feed-forward policy of
    Sub, Div, Mul, Add, Gemm, Tanh, Relu and Concat nodes, as the bundled baselines are: another
    format and another file, float rounding apart."""
    import onnx
    import torch
    from onnx import numpy_helper

    model = onnx.load(str(source))
    weights = {t.name: torch.from_numpy(numpy_helper.to_array(t).copy()) for t in model.graph.initializer}
    nodes = [(node.op_type, list(node.input), node.output[0], {a.name: onnx.helper.get_attribute_value(a)
                                                              for a in node.attribute}) for node in model.graph.node]
    binary = {"Sub": torch.sub, "Div": torch.div, "Mul": torch.mul, "Add": torch.add}
    obs_dim = model.graph.input[0].type.tensor_type.shape.dim[1].dim_value

    class Rebuilt(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.obs_dim = obs_dim
            self.params = torch.nn.ParameterDict({f"w{i}": torch.nn.Parameter(w, requires_grad=False)
                                                  for i, w in enumerate(weights.values())})
            self.names = {name: f"w{i}" for i, name in enumerate(weights)}

        def forward(self, obs):
            values = {model.graph.input[0].name: obs, **{n: self.params[k] for n, k in self.names.items()}}
            for op, inputs, output, attrs in nodes:
                args = [values[name] for name in inputs]
                if op in binary:
                    values[output] = binary[op](*args)
                elif op == "Gemm":
                    weight = args[1].T if attrs.get("transB", 0) else args[1]
                    values[output] = attrs.get("alpha", 1.0) * args[0] @ weight + attrs.get("beta", 1.0) * args[2]
                elif op in ("Tanh", "Relu"):
                    values[output] = torch.tanh(args[0]) if op == "Tanh" else torch.relu(args[0])
                elif op == "Concat":
                    values[output] = torch.cat(args, dim=attrs["axis"])
                else:
                    raise ValueError(f"torchscript_from_onnx: no {op} nodes")
            return values[model.graph.output[0].name]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tracing warns of the Python control flow it records once
        traced = torch.jit.trace(Rebuilt().eval(), torch.zeros(1, obs_dim))
    traced.save(str(path))
    return path


def disguised_copies() -> dict[str, Callable[[Path, Path], Path]]:
    """Each way a student might disguise a copy of an ONNX policy: name -> make(source, path) (the suffix
    is the variant's own). The integrity tests and benchmarks/bench_integrity.py take this one table."""
    from league.validation.probes import probe_observations

    return {
        "last layer x 1.03": lambda src, out: onnx_scaled_last_layer(src, out.with_suffix(".onnx"), 1.03),
        "outputs x 0.98": lambda src, out: onnx_scaled_outputs(src, out.with_suffix(".onnx"), 0.98),
        "outputs x 0.9 + 0.05": lambda src, out: onnx_scaled_outputs(src, out.with_suffix(".onnx"), 0.9, 0.05),
        "weights + N(0, 1e-6)": lambda src, out: onnx_weight_noise(src, out.with_suffix(".onnx"), 1e-6),
        "extra identity layer": lambda src, out: onnx_extra_identity_layer(src, out.with_suffix(".onnx")),
        "TorchScript re-export": lambda src, out: torchscript_from_onnx(src, out.with_suffix(".pt")),
        "probe-aware": lambda src, out: onnx_probe_aware(src, out.with_suffix(".onnx"), probe_observations(20)),
    }


# How students' GPU-trained models come out (a traced device is the CPU's respelt as a GPU's trace
# writes it; parameters on CUDA, their storages' location rewritten): tests/test_agents_gpu.py.
# Every one but "in-a-function" is loaded onto the CPU; that one is refused, naming CUDA.
GPU_EXPORTS = ("to-device", "to-string", "cuda-call", "device-argument", "device-attribute", "traced",
               "parameters", "in-a-function")


def torchscript_for_cuda(path: Path, how: str, seed: int = 0) -> tuple[Path, Any]:
    """A policy saved on or for a GPU as `how` says (GPU_EXPORTS), made without a GPU; returns the
    file and the CPU module it computes the same actions as."""
    import torch

    torch.manual_seed(seed)
    plain = torch.nn.Sequential(torch.nn.Linear(5, HIDDEN), torch.nn.ReLU(), torch.nn.Linear(HIDDEN, 2),
                                torch.nn.Tanh()).eval()

    def moved(x: torch.Tensor) -> torch.Tensor:
        return x.to(torch.device("cuda"))

    class OnGpu(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.net = plain
            self.device = torch.device("cuda")

    class ToDevice(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(obs.to(torch.device("cuda"))).cpu()

    class ToString(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(obs.to("cuda")).cpu()

    class CudaCall(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(obs.cuda()).cpu()

    class DeviceArgument(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(obs + torch.zeros(5, device="cuda")).cpu()

    class DeviceAttribute(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(obs.to(self.device)).cpu()

    class InAFunction(OnGpu):
        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            return self.net(moved(obs)).cpu()

    scripted = {"to-device": ToDevice, "to-string": ToString, "cuda-call": CudaCall,
                "device-argument": DeviceArgument, "device-attribute": DeviceAttribute, "in-a-function": InAFunction}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        if how == "traced":
            class Traced(OnGpu):  # the trace records the device of `.to(device)`
                def forward(self, obs: torch.Tensor) -> torch.Tensor:
                    return self.net(obs.to(torch.device("cpu")))

            torch.jit.trace(Traced(), torch.zeros(1, 5)).save(str(path))
            return _respell(path, 'torch.device("cpu")', 'torch.device("cuda:0")'), plain
        if how == "parameters":
            torch.jit.script(plain).save(str(path))
            return _storages_on_cuda(path), plain
        torch.jit.script(scripted[how]()).save(str(path))
    return path, plain


def _storages_on_cuda(path: Path) -> Path:
    """The archive's tensors as saved from a GPU: their storages' location (a pickled string) cuda:0."""
    entries = []
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            data = archive.read(info)
            if info.filename.endswith(("/data.pkl", "/constants.pkl")):
                data = data.replace(b"X\x03\x00\x00\x00cpu", b"X\x06\x00\x00\x00cuda:0")  # BINUNICODE, its length
            entries.append((info, data))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as archive:
        for info, data in entries:
            archive.writestr(info, data)
    return path

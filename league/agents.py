"""Agents: one interface from observations to actions, whatever the model behind it.

An agent maps a batch of observations, float32 ``(batch, obs_dim)``, to a batch of actions,
float32 ``(batch, 2)`` = ``[acceleration, turn]`` clipped to [-1, 1]. ``obs_dim`` is 5 for the
compact observation ``[direction, left, max, right, speed]`` and 20 for the lidar one
(19 rays + speed). Loaders cover ONNX files (ONNX Runtime, single-threaded), TorchScript files
(``torch.jit.load``, never ``torch.load`` or any pickle), Python callables and the built-in
heuristic driver of the reference implementation.

torch and onnxruntime are optional: they are imported only when a file of their kind is loaded
(onnxruntime with its telemetry off: see `import_onnxruntime`).
"""
from __future__ import annotations

import functools
import os
import sys
import unicodedata
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from league.constants import (
    COMPACT_DIM, LIDAR_DIM, MAX_TURN, MODEL_SUFFIXES, N_RAYS, OBSERVATION_DIMS, is_pickle, is_torchscript_layout,
    is_zip,
)

OBS_DIMS = tuple(OBSERVATION_DIMS.values())
HEURISTIC_TARGET_SPEED = 0.25  # world units per second
HEURISTIC_ACC, HEURISTIC_BRAKE = 0.5, -0.2

INSTALL_ONNX = "pip install onnx onnxruntime onnxscript (the toolkit's onnx extra)"
# PyTorch's CPU wheels (a plain `pip install torch` on Linux brings ~4 GB of CUDA libraries)
INSTALL_TORCH = "pip install torch --index-url https://download.pytorch.org/whl/cpu"



class AgentError(Exception):
    """An agent that cannot be loaded or that failed while acting.

    ``reason`` is a one-line, human-readable explanation (shown to students, stored by the
    server as the reason of a DNF). ``isolable`` is True when the failure is the model's answer
    to these observations (it raised, or returned a wrong shape or non-finite actions): asked
    again row by row, the model fails only on the observations that make it fail, so a batched
    evaluation fails only those episodes. It is False for failures of the agent as a whole (it
    cannot load, missed a deadline, its process died, the run was cancelled).
    """

    def __init__(self, reason: str, *, isolable: bool = False):
        super().__init__(reason)
        self.reason = reason
        self.isolable = isolable


class Agent:
    """A driving policy: ``agent(obs) -> actions``, batched, validated and clipped.

    Attributes:
        obs_dim: 5 (compact observation) or 20 (lidar observation); evaluations build the
            environment's observation from it.
        name: shown in results, tables and race legends.
        kind: where the policy comes from: "onnx", "torchscript", "python" or "heuristic".
        fixed_batch: the model takes one observation at a time (an export with batch size 1):
            a batch is passed to it row by row, in this process (set by the loaders' dry run).

    Calling the agent with float32 observations of shape ``(batch, obs_dim)`` (a single
    observation of shape ``(obs_dim,)`` is treated as a batch of one) returns float32 actions
    of shape ``(batch, 2)`` = ``[acceleration, turn]``, clipped to [-1, 1]. Any failure of the
    model (an exception, a wrong shape, a non-float or non-finite output) raises
    :class:`AgentError`, which evaluations record as a DNF with its reason.

    Subclasses implement ``_act(obs) -> array-like`` (and may override ``reset``, called before
    every evaluation and race). An agent living elsewhere (e.g. in a sandbox process) only needs
    the same ``obs_dim``, ``name`` and ``__call__`` raising AgentError on failure (isolable
    when the model itself failed on the observations).
    """

    kind = "python"

    def __init__(self, obs_dim: int, name: str, *, fixed_batch: bool = False):
        if obs_dim not in OBS_DIMS:
            raise AgentError(f"observation size {obs_dim} is not supported: use 5 (compact) or 20 (lidar)")
        self.obs_dim = int(obs_dim)
        self.name = name
        self.fixed_batch = fixed_batch

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check_observations(obs)
        if self.fixed_batch and len(obs) > 1:
            return self._checked_act(obs, self._act_rows)
        return self._checked_act(obs)

    def _checked_act(self, obs: np.ndarray, act: Callable[[np.ndarray], Any] | None = None) -> np.ndarray:
        try:
            raw = (act or self._act)(obs)
        except AgentError:
            raise
        except Exception as error:  # the model is foreign code: any failure is the agent's
            raise AgentError(f"the model raised {type(error).__name__}: {_one_line(error)}", isolable=True) from error
        return check_actions(raw, batch=obs.shape[0])

    def _act(self, obs: np.ndarray) -> Any:
        raise NotImplementedError

    def _act_rows(self, obs: np.ndarray) -> np.ndarray:
        """The model's answers for a batch, asked one observation at a time (`fixed_batch`)."""
        return np.concatenate([check_actions(self._act(obs[k:k + 1]), batch=1) for k in range(len(obs))])

    def request(self, obs: np.ndarray) -> Callable[[], np.ndarray]:
        """Ask for the actions of `obs` now, get them (or the AgentError) by calling the result.

        In-process agents compute when the result is called; an agent in another process sends
        the request at once, so a race asks every car before it waits for any answer.
        """
        return functools.partial(self, obs)

    def reset(self) -> None:
        """Called before every episode and race: a hook for stateful policies or per-episode budgets."""

    def close(self) -> None:
        """Release what the agent holds (a session, a process); a no-op by default."""

    def __enter__(self) -> Agent:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} kind={self.kind} obs_dim={self.obs_dim}>"

    def _check_observations(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if obs.ndim == 1:
            obs = obs[None, :]
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"agent {self.name!r} expects observations of shape (batch, {self.obs_dim}), "
                             f"got {obs.shape}")
        return obs


def check_actions(raw: Any, batch: int) -> np.ndarray:
    """Validate a model's output for ``batch`` observations; return float32 (batch, 2) clipped."""
    actions = _to_numpy(raw)
    if actions.dtype.kind not in "f":
        raise AgentError(f"the model's output is not floating point (dtype {actions.dtype}); actions must be float32",
                         isolable=True)
    if actions.shape == (2,) and batch == 1:
        actions = actions[None, :]
    if actions.ndim != 2 or actions.shape[0] != batch or actions.shape[1] != 2:
        raise AgentError(_wrong_shape_message(actions.shape, batch), isolable=True)
    if not np.isfinite(actions).all():
        raise AgentError("the model returned NaN or infinite actions", isolable=True)
    # the ufuncs themselves: np.clip's and np.all's Python wrappers cost more than the work on (100, 2)
    return np.minimum(np.maximum(actions, -1.0, dtype=np.float32), 1.0, dtype=np.float32)


def _wrong_shape_message(shape: tuple, batch: int) -> str:
    if len(shape) == 2 and shape[0] == batch:
        return (f"the model returns {shape[1]} values per observation, expected 2 "
                f"([acceleration, turn]); output shape {shape}")
    return f"the model's output has shape {shape}, expected ({batch}, 2) for {batch} observations"


def _to_numpy(raw: Any) -> np.ndarray:
    """Output of any framework -> numpy; of several outputs (a tuple or list of arrays), the first."""
    if isinstance(raw, (tuple, list)) and raw and _is_array_like(raw[0]):
        raw = raw[0]
    if isinstance(raw, dict) and raw:
        raw = next(iter(raw.values()))
    if hasattr(raw, "detach"):  # torch tensor
        raw = raw.detach().cpu().numpy()
    elif hasattr(raw, "numpy") and not isinstance(raw, np.ndarray):  # tensorflow tensor
        raw = raw.numpy()
    try:
        return np.asarray(raw)
    except Exception as error:
        raise AgentError(f"the model's output is not an array ({type(raw).__name__})", isolable=True) from error


def _is_array_like(value: Any) -> bool:
    return hasattr(value, "shape") or isinstance(value, (list, tuple))


def _one_line(error: BaseException, limit: int = 300) -> str:
    return plain_text(str(error), limit)


def plain_text(text: str, limit: int = 300) -> str:
    """Text a model produced, made safe to show: one line, no control or format characters (a
    right-to-left override would reverse what follows it on a page), at most `limit` characters."""
    text = "".join(" " if char.isspace() else char for char in text
                   if char.isspace() or unicodedata.category(char) not in ("Cc", "Cf", "Co", "Cs"))
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


# --------------------------------------------------------------------------- heuristic driver


def compact_from_lidar(lidar_obs: np.ndarray) -> np.ndarray:
    """The compact observation (SPEC "Lidar and observation") of lidar observations (batch, 20)."""
    rays = lidar_obs[:, :N_RAYS]
    k = np.argmax(rays, axis=1)  # first maximum, as the reference
    rows = np.arange(rays.shape[0])
    compact = np.empty((rays.shape[0], COMPACT_DIM), dtype=np.float32)
    compact[:, 0] = -MAX_TURN + k * (2 * MAX_TURN) / (N_RAYS - 1)
    compact[:, 1] = rays[rows, np.maximum(k - 1, 0)]
    compact[:, 2] = rays[rows, k]
    compact[:, 3] = rays[rows, np.minimum(k + 1, N_RAYS - 1)]
    compact[:, 4] = lidar_obs[:, N_RAYS]
    return compact


def heuristic_actions(compact_obs: np.ndarray) -> np.ndarray:
    """SPEC's reference driver: steer toward the free direction, hold the speed near 0.25."""
    direction, speed = compact_obs[:, 0], compact_obs[:, 4]
    actions = np.empty((compact_obs.shape[0], 2), dtype=np.float32)
    actions[:, 0] = np.where(speed < HEURISTIC_TARGET_SPEED, HEURISTIC_ACC, HEURISTIC_BRAKE)
    actions[:, 1] = np.clip(-direction / MAX_TURN, -1.0, 1.0)  # positive turn = right
    return actions


class HeuristicAgent(Agent):
    kind = "heuristic"

    def _act(self, obs: np.ndarray) -> np.ndarray:
        compact = obs if self.obs_dim == COMPACT_DIM else compact_from_lidar(obs)
        return heuristic_actions(compact)


def heuristic_agent(obs_dim: int = COMPACT_DIM) -> Agent:
    """The built-in driver of SPEC: "heuristic" on compact (5), "heuristic-lidar" on lidar (20) observations."""
    return HeuristicAgent(obs_dim, "heuristic" if obs_dim == COMPACT_DIM else "heuristic-lidar")


# --------------------------------------------------------------------------- Python callables


class CallableAgent(Agent):
    kind = "python"

    def __init__(self, fn: Callable[[np.ndarray], Any], obs_dim: int, name: str):
        super().__init__(obs_dim, name)
        self._fn = fn

    def _act(self, obs: np.ndarray) -> Any:
        return self._fn(obs)


def callable_agent(fn: Callable[[np.ndarray], Any], obs_dim: int = COMPACT_DIM, name: str | None = None,
                   dry_run: bool = True) -> Agent:
    """Wrap ``fn(obs (batch, obs_dim) float32) -> actions (batch, 2)`` as an :class:`Agent`.

    ``fn`` may return a numpy array, a list, a torch or TensorFlow tensor, or several outputs
    (the first is used). With ``dry_run`` the contract is checked at once.
    """
    agent = CallableAgent(fn, obs_dim, name or getattr(fn, "__name__", "python-agent"))
    if dry_run:
        dry_run_check(agent)
    return agent


# --------------------------------------------------------------------------- TorchScript


class TorchAgent(Agent):
    kind = "torchscript"

    def __init__(self, module: Any, obs_dim: int, name: str):
        super().__init__(obs_dim, name)
        self._module = module
        self._torch = sys.modules["torch"]

    def _act(self, obs: np.ndarray) -> Any:
        with self._torch.no_grad():
            return self._module(self._torch.from_numpy(obs))

    def _act_rows(self, obs: np.ndarray) -> Any:
        """One observation a call, under one no_grad and checked once (a third of the cost of
        each row on its own, for a small model: bench_toolkit.py (e))."""
        torch = self._torch
        with torch.no_grad():
            return torch.cat([torch.as_tensor(self._module(row)).reshape(1, -1)
                              for row in torch.from_numpy(obs).split(1)])


def torch_module_agent(module: Any, obs_dim: int | None = None, name: str | None = None) -> Agent:
    """Wrap an in-memory torch module (scripted or not); ``obs_dim`` found by a dry run if omitted."""
    module.eval()
    name = name or type(module).__name__
    return _with_probed_obs_dim(lambda dim: TorchAgent(module, dim, name), obs_dim, _declared_obs_dim(module))


def _load_torchscript(path: Path, obs_dim: int | None, name: str) -> Agent:
    _refuse_pickles(path)
    torch = _import_optional("torch", INSTALL_TORCH, "TorchScript")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # torch.jit is in maintenance, still supported
            module = torch.jit.load(str(path), map_location="cpu")
    except Exception as error:
        raise AgentError(f"{path.name} is not a loadable TorchScript file (truncated or corrupt?): "
                         f"{_one_line(error, 200)}") from error
    onto_cpu(module)
    module.eval()
    return _with_probed_obs_dim(lambda dim: TorchAgent(module, dim, name), obs_dim, _declared_obs_dim(module))


# --------------------------------------------------------------------------- models from GPUs

# The fix, for a model that needs CUDA (students train on GPUs; the league runs models on CPUs).
EXPORT_FROM_CPU = ("export it from the CPU: model.cpu() before torch.jit.script / torch.jit.trace (a traced "
                   "model with CPU example inputs), and no device in forward (no .cuda(), no .to(\"cuda\"))")


def onto_cpu(module: Any) -> None:
    """A TorchScript module saved on or for a GPU, made to run on the CPU as it would on the GPU.

    Its tensors are on the CPU already (torch.jit.load's map_location="cpu"); what names CUDA is in
    its methods: device constants (`.to("cuda")`, `device="cuda"`, a trace's recorded device), which
    become the CPU; `.cuda()` calls, which are dropped (on the CPU they would copy to the GPU and
    nothing else); Device attributes its methods read (`self.device`), set to the CPU. Done before
    the module first runs (its graphs are compiled then). What is left, a device in a function the
    methods call, refuses the model with the fix (AgentError): `cuda_uses` finds it on structure.
    """
    import torch

    for _, submodule in module.named_modules():
        for name in submodule._c._method_names():
            graph = submodule._c._get_method(name).graph
            _cpu_constants(torch, graph, graph)
            _cpu_device_attributes(torch, submodule, graph)
        for hook in [*submodule._c._get_forward_pre_hooks(), *submodule._c._get_forward_hooks()]:
            _cpu_constants(torch, hook.graph, hook.graph)
    left = cuda_uses(module)
    if left:
        raise AgentError(f"the model needs CUDA (a GPU) and the league runs models on the CPU: {left[0]}; "
                         f"{EXPORT_FROM_CPU}")


def _cpu_constants(torch: Any, graph: Any, block: Any) -> None:
    for node in list(block.nodes()):
        for inner in node.blocks():
            _cpu_constants(torch, graph, inner)
        if node.kind() == "aten::cuda" and len(list(node.inputs())) == 1:  # Tensor.cuda(), no options
            node.output().replaceAllUsesWith(node.input())
            node.destroy()
        elif _is_cuda_constant(node):
            with graph.insert_point_guard(node):
                cpu = graph.insertConstant(torch.device("cpu"))
            node.output().replaceAllUsesWith(cpu)
            node.destroy()


def _cpu_device_attributes(torch: Any, submodule: Any, graph: Any) -> None:
    this = next(graph.inputs())  # self
    for node in graph.findAllNodes("prim::GetAttr"):
        name = node.s("name")
        if node.input().unique() == this.unique():
            if node.output().type().kind() == "DeviceObjType" and submodule._c.getattr(name).type == "cuda":
                submodule._c.setattr(name, torch.device("cpu"))


def _is_cuda_constant(node: Any) -> bool:
    return (node.kind() == "prim::Constant" and node.output().type().kind() == "DeviceObjType"
            and node.output().toIValue().type == "cuda")


def cuda_uses(module: Any) -> list[str]:
    """Where a loaded TorchScript module names CUDA, in its methods and hooks with every call
    inlined: a CUDA device constant or a `.cuda()` call ('Policy.forward names the device cuda')."""
    import torch

    found = []
    for prefix, submodule in module.named_modules():
        owner = prefix or module.original_name
        graphs = [(f"{owner}.{name}", submodule._c._get_method(name).graph)
                  for name in submodule._c._method_names()]
        graphs += [(f"a hook of {owner}", hook.graph)
                   for hook in [*submodule._c._get_forward_pre_hooks(), *submodule._c._get_forward_hooks()]]
        for where, graph in graphs:
            inlined = graph.copy()
            torch._C._jit_pass_inline(inlined)
            for node in _all_nodes(inlined.block()):
                if node.kind() == "aten::cuda":
                    found.append(f"{where} calls .cuda()")
                elif _is_cuda_constant(node):
                    found.append(f"{where} names the device {node.output().toIValue()}")
    return found


def _all_nodes(block: Any) -> list[Any]:
    nodes = []
    for node in block.nodes():
        nodes.append(node)
        for inner in node.blocks():
            nodes += _all_nodes(inner)
    return nodes


def _refuse_pickles(path: Path) -> None:
    """TorchScript is a zip with code/ and constants.pkl; a bare pickle or a torch.save checkpoint is refused unread."""
    head = _read_head(path)
    if is_pickle(head):
        raise AgentError(f"{path.name} is a Python pickle, not TorchScript; pickles can run arbitrary code and are "
                         "never loaded. Export with torch.jit.script(model).save(path) or torch.onnx.export")
    if not is_zip(head):
        raise AgentError(f"{path.name} is not a TorchScript file (not a zip archive)")
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
    except zipfile.BadZipFile as error:
        raise AgentError(f"{path.name} is a damaged zip archive (truncated?), "
                         "not a loadable TorchScript file") from error
    if not is_torchscript_layout(names):
        raise AgentError(f"{path.name} is a torch.save checkpoint (a pickle), not TorchScript; it is never loaded. "
                         "Export with torch.jit.script(model).save(path) or torch.onnx.export")


def _declared_obs_dim(module: Any) -> int | None:
    value = getattr(module, "obs_dim", None)
    return int(value) if isinstance(value, int) and value in OBS_DIMS else None


def export_torchscript(module: Any, path: str | os.PathLike) -> Path:
    """Save a torch policy as TorchScript (``torch.jit.script``, or tracing when scripting fails)."""
    torch = _import_optional("torch", INSTALL_TORCH, "TorchScript")
    module.eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            scripted = torch.jit.script(module)
        except Exception:  # not scriptable (dynamic Python): tracing records the forward pass instead
            scripted = torch.jit.trace(module, torch.zeros(1, _declared_obs_dim(module) or COMPACT_DIM))
        scripted.save(str(path))
    return Path(path)


# --------------------------------------------------------------------------- ONNX


class OnnxAgent(Agent):
    kind = "onnx"

    def __init__(self, session: Any, obs_dim: int, name: str, *, fixed_batch: bool, rank: int, input_dtype: type):
        super().__init__(obs_dim, name, fixed_batch=fixed_batch or rank == 1)
        self._session = session
        self._input = session.get_inputs()[0].name
        self._outputs = [session.get_outputs()[0].name]
        self._rank = rank  # 1: the model takes one observation, shape (obs_dim,)
        self._input_dtype = input_dtype

    def _act(self, obs: np.ndarray) -> np.ndarray:
        obs = obs.astype(self._input_dtype, copy=False)
        if self._rank == 1:
            return np.asarray(self._run(obs[0])).reshape(1, -1)
        return self._run(obs)

    def _run(self, obs: np.ndarray) -> np.ndarray:
        return self._session.run(self._outputs, {self._input: obs})[0]


ONNX_INPUT_DTYPES = {"tensor(float)": np.float32, "tensor(double)": np.float64, "tensor(float16)": np.float16}


def _load_onnx(path: Path, obs_dim: int | None, name: str) -> Agent:
    ort = import_onnxruntime()
    session = _onnx_session(ort, path)
    model_input = session.get_inputs()[0]
    shape = list(model_input.shape)
    if model_input.type not in ONNX_INPUT_DTYPES:
        raise AgentError(f"the model's input {model_input.name!r} is {model_input.type}; "
                         "it must be float32 observations")
    if len(shape) not in (1, 2):
        raise AgentError(f"the model's input has shape {shape}; expected (batch, 5) or (batch, 20)")
    size = shape[-1]
    if isinstance(size, int) and size not in OBS_DIMS:
        raise AgentError(f"wrong input size: the model takes {size} values per observation, "
                         "expected 5 (compact observation) or 20 (lidar observation)")
    if obs_dim is not None and isinstance(size, int) and size != obs_dim:
        raise AgentError(f"the model takes {size} values per observation, but obs_dim={obs_dim} was requested")
    fixed_batch = len(shape) == 1 or isinstance(shape[0], int)
    if len(shape) == 2 and shape[0] == 1 and isinstance(size, int):
        session, fixed_batch = _free_the_batch(ort, path, session, size)

    def build(dim: int) -> Agent:
        return OnnxAgent(session, dim, name, fixed_batch=fixed_batch, rank=len(shape),
                         input_dtype=ONNX_INPUT_DTYPES[model_input.type])

    return _with_probed_obs_dim(build, obs_dim, size if isinstance(size, int) else None)


def _free_the_batch(ort: Any, path: Path, session: Any, obs_dim: int) -> tuple[Any, bool]:
    """(session, fixed_batch) for an export fixed to batch size 1: the same graph with its batch
    dimension left free, if it answers a batch of probe observations exactly as the original
    answers each of them (most such exports are MLPs, which do); else the original, row by row.
    A lockstep evaluation then makes one call per step instead of one per running episode."""
    try:
        import onnx
    except ImportError:  # onnxruntime without onnx (the toolkit's `onnx` extra has both)
        return session, True
    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception:  # noqa: BLE001 - ONNX Runtime read it: whatever onnx thinks, it runs row by row
        return session, True
    initializers = {tensor.name for tensor in model.graph.initializer}
    for value in [*(v for v in model.graph.input if v.name not in initializers), *model.graph.output]:
        dims = value.type.tensor_type.shape.dim
        if not dims or dims[0].dim_value != 1:
            return session, True
        dims[0].dim_param = "batch"  # (clears dim_value: one of the two)
    del model.graph.value_info[:]  # shapes inferred for a batch of one
    dtype = ONNX_INPUT_DTYPES[session.get_inputs()[0].type]
    probes = np.random.default_rng(0).uniform(-0.2, 1.0, (4, obs_dim)).astype(dtype)
    name, outputs = session.get_inputs()[0].name, [session.get_outputs()[0].name]
    try:
        batched = _onnx_session(ort, model.SerializeToString())
        rows = [session.run(outputs, {name: probes[k:k + 1]})[0] for k in range(len(probes))]
        answer = batched.run(outputs, {name: probes})[0]
    except Exception:  # noqa: BLE001 - e.g. a Reshape to a constant (1, n): the batch is not free
        return session, True
    if np.shape(answer) != (len(probes), *np.shape(rows[0])[1:]) or not np.array_equal(answer, np.concatenate(rows)):
        return session, True
    return batched, False


def _onnx_session(ort: Any, model: Path | bytes) -> Any:
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1  # one core per evaluation: the league runs many side by side
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.log_severity_level = 3  # errors only: no warnings on the students' terminals
    try:
        return ort.InferenceSession(model if isinstance(model, bytes) else str(model), options,
                                    providers=["CPUExecutionProvider"])
    except Exception as error:
        path, message = Path(model if isinstance(model, Path) else "model.onnx"), _one_line(error, 200)
        if "protobuf" in message.lower():
            raise AgentError(f"{path.name} is not an ONNX model (or the file is truncated): {message}") from error
        raise AgentError(f"ONNX Runtime cannot load {path.name}: {message}") from error


def export_onnx(module: Any, path: str | os.PathLike, obs_dim: int = COMPACT_DIM) -> Path:
    """Export a torch policy to ONNX with a dynamic batch: input "obs" (batch, obs_dim), output "actions"."""
    torch = _import_optional("torch", INSTALL_TORCH, "TorchScript")
    module.eval()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript-based exporter is deprecated but needs no onnxscript
        torch.onnx.export(module, (torch.zeros(1, obs_dim),), str(path), input_names=["obs"], output_names=["actions"],
                          dynamic_axes={"obs": {0: "batch"}, "actions": {0: "batch"}}, opset_version=17, dynamo=False)
    return Path(path)


def export_heuristic_onnx(path: str | os.PathLike) -> Path:
    """Write the heuristic driver as an ONNX model (compact observations), e.g. as a bundled agent.

    The graph is the same arithmetic as :func:`heuristic_actions`, so it drives identically.
    """
    onnx = _import_optional("onnx", INSTALL_ONNX, "ONNX")
    helper, TensorProto = onnx.helper, onnx.TensorProto

    def const(name: str, values: list, dtype: int = TensorProto.FLOAT, dims: list | None = None):
        return helper.make_tensor(name, dtype, [len(values)] if dims is None else dims, values)

    nodes = [
        helper.make_node("Gather", ["obs", "direction_index"], ["direction"], axis=1),
        helper.make_node("Gather", ["obs", "speed_index"], ["speed"], axis=1),
        helper.make_node("Div", ["direction", "minus_max_turn"], ["turn_raw"]),
        helper.make_node("Clip", ["turn_raw", "minus_one", "one"], ["turn"]),
        helper.make_node("Less", ["speed", "target_speed"], ["slow"]),
        helper.make_node("Where", ["slow", "acc", "brake"], ["acceleration"]),
        helper.make_node("Concat", ["acceleration", "turn"], ["actions"], axis=1),
    ]
    initializers = [
        const("direction_index", [0], TensorProto.INT64), const("speed_index", [4], TensorProto.INT64),
        const("minus_max_turn", [-MAX_TURN], dims=[]), const("minus_one", [-1.0], dims=[]),
        const("one", [1.0], dims=[]), const("target_speed", [HEURISTIC_TARGET_SPEED], dims=[]),
        const("acc", [HEURISTIC_ACC], dims=[]), const("brake", [HEURISTIC_BRAKE], dims=[]),
    ]
    graph = helper.make_graph(
        nodes, "heuristic_driver",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", COMPACT_DIM])],
        [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", 2])],
        initializers,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="microracer-league")
    model.ir_version = 8  # readable by every ONNX Runtime >= 1.10
    onnx.checker.check_model(model)
    path = Path(path)
    onnx.save(model, str(path))
    return path


# --------------------------------------------------------------------------- loading and dry runs


def as_agent(actor: Any, obs_dim: int | None = None, name: str | None = None) -> Agent:
    """Turn anything that drives into an :class:`Agent` (what the thesis called an actor included).

    Accepted: an Agent (returned as is); a path or "heuristic" (``load_agent``); a torch module
    (``obs_dim`` probed if omitted); any callable mapping a batch of states to actions, e.g. a
    Keras model or a function (``obs_dim`` 5 if omitted); an object with ``predict``. Of
    several outputs, the first is the action.
    """
    if isinstance(actor, Agent):
        return actor
    if isinstance(actor, (str, os.PathLike)):
        return load_agent(actor, name=name, obs_dim=obs_dim)
    name = name or _actor_name(actor)
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(actor, torch.nn.Module):
        return torch_module_agent(actor, obs_dim=obs_dim, name=name)
    if callable(actor):
        return callable_agent(actor, obs_dim=obs_dim or COMPACT_DIM, name=name)
    if hasattr(actor, "predict"):
        return callable_agent(actor.predict, obs_dim=obs_dim or COMPACT_DIM, name=name)
    raise TypeError(f"cannot drive with {type(actor).__name__}: give an Agent, a model file, a callable or "
                    "an object with predict()")


def _actor_name(actor: Any) -> str:
    name = getattr(actor, "name", None)
    if isinstance(name, str) and name:
        return name
    return getattr(actor, "__name__", None) or type(actor).__name__


def load_agent(path_or_name: str | os.PathLike, name: str | None = None, obs_dim: int | None = None) -> Agent:
    """Load an agent from a file, or the built-in driver by name, and check it with a dry run.

    Args:
        path_or_name: ``"heuristic"`` (``"heuristic-lidar"`` for its lidar form), or the path of
            an ONNX file (``.onnx``) or a TorchScript file (``.pt`` and the others of
            ``league.constants.MODEL_SUFFIXES``).
            The format is recognised from the file's content first, its extension second.
        name: the agent's display name (default: the file's stem).
        obs_dim: force 5 or 20; by default ONNX models declare it in their input shape and
            TorchScript models are probed with 5, then 20 values (or declare an ``obs_dim``
            attribute).

    Raises:
        AgentError: with a clear reason when the file is missing, empty, not a model, truncated,
            a pickle, has a wrong input size or output shape, returns non-float or NaN actions.
            A missing optional package raises an AgentError naming the install command.
    """
    text = os.fspath(path_or_name)
    if text in ("heuristic", "heuristic-lidar"):
        return heuristic_agent(LIDAR_DIM if text.endswith("lidar") else COMPACT_DIM)
    path = Path(text)
    if not path.is_file():
        raise AgentError(f"no such agent file: {text} (give an .onnx or TorchScript .pt file, or 'heuristic')")
    if path.stat().st_size == 0:
        raise AgentError(f"{path.name} is empty")
    name = name or path.stem
    if _looks_like_torchscript(path):
        return _load_torchscript(path, obs_dim, name)
    return _load_onnx(path, obs_dim, name)


def _looks_like_torchscript(path: Path) -> bool:
    head = _read_head(path)
    if is_zip(head) or is_pickle(head):
        return True
    return MODEL_SUFFIXES.get(path.suffix.lower()) == "torchscript"


def _read_head(path: Path, size: int = 8) -> bytes:
    with open(path, "rb") as handle:
        return handle.read(size)


def dry_run_observations(obs_dim: int, batch: int = 2) -> np.ndarray:
    """Plausible observations (a straight road ahead, cruising speed) for a contract check."""
    if obs_dim == COMPACT_DIM:
        row = [0.05, 0.3, 0.35, 0.3, 0.25]
    else:
        row = list(np.linspace(0.1, 0.4, N_RAYS // 2 + 1)) + list(np.linspace(0.4, 0.1, N_RAYS // 2 + 1))[1:] + [0.25]
    return np.tile(np.asarray(row, dtype=np.float32), (batch, 1))


def dry_run_check(agent: Agent) -> None:
    """Call the agent on a batch of 2 and on a batch of 1; raise AgentError if it breaks.

    A model that fails on the batch of 2 but answers the batch of 1 takes one observation at a
    time (an export fixed to batch size 1): it becomes `fixed_batch`, called row by row.
    """
    try:
        agent(dry_run_observations(agent.obs_dim, 2))
    except AgentError as error:
        if not error.isolable or agent.fixed_batch:
            raise
        agent(dry_run_observations(agent.obs_dim, 1))  # fails too: the model is broken, not batch-bound
        agent.fixed_batch = True
        agent(dry_run_observations(agent.obs_dim, 2))
    else:
        agent(dry_run_observations(agent.obs_dim, 1))


def _with_probed_obs_dim(build: Callable[[int], Agent], requested: int | None, declared: int | None) -> Agent:
    """Build the agent for the requested/declared size, or try 5 then 20 and keep the one that works."""
    if requested is not None or declared is not None:
        agent = build(requested or declared)
        dry_run_check(agent)
        return agent
    failures = []
    for dim in OBS_DIMS:
        agent = build(dim)
        try:
            dry_run_check(agent)
            return agent
        except AgentError as error:
            failures.append((dim, error.reason))
    if all(_model_raised(reason) for _, reason in failures):
        raise AgentError("wrong input size? the model fails on 5 (compact) and on 20 (lidar) observation values: "
                         f"{failures[0][1]}")
    dim, reason = next((d, r) for d, r in failures if not _model_raised(r))
    raise AgentError(f"{reason} (dry run with {dim} observation values)")


def _model_raised(reason: str) -> bool:
    return reason.startswith("the model raised")


def import_onnxruntime() -> Any:
    """onnxruntime without its telemetry (uploads, an offline cache in ~/.cache and a thread of its
    own since 1.32), unless ORT_DISABLE_TELEMETRY says otherwise: it must be set before the import."""
    os.environ.setdefault("ORT_DISABLE_TELEMETRY", "1")
    return _import_optional("onnxruntime", INSTALL_ONNX, "ONNX")


def _import_optional(module: str, install: str, purpose: str) -> Any:
    try:
        return __import__(module)
    except ImportError as error:
        raise AgentError(f"loading {purpose} agents needs the '{module}' package: {install}") from error

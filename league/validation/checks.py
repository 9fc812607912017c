"""Static checks of untrusted model files, run before a model is loaded: in the server's sandbox
(league/server/sandbox/child.py) and by `league check` (league.validation.local), the same code.

A policy is an MLP or a CNN: the allow-lists hold what those need (as exported by
torch.onnx / torch.jit) and nothing that touches files, processes, threads or randomness.
PyTorch's security policy treats a TorchScript file like an executable of unknown origin, and
ONNX files have had path-traversal and out-of-bounds bugs, so anything unusual is refused.
"""
from __future__ import annotations

import ast
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from league.constants import is_pickle, is_torchscript_layout

ONNX_DOMAINS = ("", "ai.onnx")
# Operator sets a model may declare: the ONNX standard's own. tf2onnx and Keras declare ai.onnx.ml
# (the standard's classical-ML operators) in every model; its operators are still refused, node by node.
ONNX_IMPORTS = (*ONNX_DOMAINS, "ai.onnx.ml")
ONNX_OPS = frozenset("""
Abs Acos Add And ArgMax ArgMin Asin Atan AveragePool BatchNormalization Cast CastLike Ceil Celu Clip Concat
Constant ConstantOfShape Conv Cos Div Dropout Elu Equal Erf Exp Expand Flatten Floor Gather GatherElements Gelu
Gemm GlobalAveragePool GlobalMaxPool Greater GreaterOrEqual HardSigmoid HardSwish Identity InstanceNormalization
LayerNormalization LeakyRelu Less LessOrEqual Log LogSoftmax MatMul Max MaxPool Mean Min Mish Mod Mul Neg Not Or
Pad Pow PRelu Range Reciprocal ReduceL2 ReduceMax ReduceMean ReduceMin ReduceProd ReduceSum Relu Reshape Round
Selu Shape Sigmoid Sign Sin Size Slice Softmax Softplus Softsign Split Sqrt Squeeze Sub Sum Tan Tanh Tile
Transpose Trilu Unsqueeze Where Xor
""".split())

TORCH_PRIM_OPS = frozenset("""
Constant GetAttr ListConstruct ListUnpack TupleConstruct TupleUnpack TupleIndex DictConstruct If Loop
NumToTensor unchecked_cast RaiseException Uninitialized dtype device layout min max abs Print isinstance
""".split())
# (`cpu`: the `.cpu()` a GPU-trained model ends forward with, the identity on the CPU: agents.onto_cpu)
TORCH_ATEN_OPS = frozenset("""
linear addmm matmul mm bmm t relu relu_ leaky_relu leaky_relu_ elu elu_ selu celu gelu silu mish hardswish
hardsigmoid hardtanh hardtanh_ relu6 prelu softplus softsign tanh tanh_ sigmoid sigmoid_ softmax log_softmax
_convolution conv1d conv2d conv3d convolution max_pool1d max_pool2d avg_pool1d avg_pool2d adaptive_avg_pool1d
adaptive_avg_pool2d adaptive_max_pool1d adaptive_max_pool2d batch_norm layer_norm group_norm instance_norm
dropout dropout_ feature_dropout alpha_dropout flatten view view_as reshape reshape_as squeeze unsqueeze
permute transpose contiguous expand expand_as repeat cat concat stack split chunk unbind narrow select slice
index_select gather index clamp clamp_ clip clamp_min clamp_max add add_ sub sub_ rsub mul mul_ div div_
floor_divide floordiv remainder neg abs exp log log1p log2 sqrt rsqrt pow square reciprocal sign floor ceil
round trunc sin cos atan atan2 mean sum prod max min amax amin maximum minimum argmax argmin norm std var
where eq ne lt le gt ge logical_and logical_or logical_not zeros ones zeros_like ones_like full full_like
arange tensor scalar_tensor to type_as float double detach clone copy_ fill_ zero_ size dim numel len
__getitem__ __is__ __isnot__ __not__ __and__ __or__ __contains__ list append Int Float Bool ScalarImplicit
format warn item is_floating_point new_zeros new_ones masked_fill where_ erf lerp tensor_split movedim cpu
""".split())
# Methods that run while a TorchScript file is loaded (the unpickler calls __setstate__; its pair
# makes no sense alone): refused outright, wherever they are defined.
LOAD_TIME_METHODS = frozenset({"__setstate__", "__getstate__"})
# How to get one file: torch writes weights beside the model by default; `league submit` packs them
SELF_CONTAINED = "torch.onnx.export(..., external_data=False), or `league submit`, which packs them in"
MAX_CODE_FILE = 4 * 1024 * 1024  # bytes of TorchScript source per file (zip bombs are not read)


class ModelRejected(Exception):
    """The file is refused before loading; `reason` is shown to the student."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


# --------------------------------------------------------------------------- ONNX


def check_onnx(path: Path) -> None:
    import onnx

    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception as error:
        raise ModelRejected(f"not an ONNX model (or the file is truncated): {_short(error)}") from error
    _check_onnx_imports(model)
    for graph in _onnx_graphs(model.graph):
        _check_onnx_tensors(graph)
        for node in graph.node:
            _check_onnx_node(node)
    try:
        onnx.checker.check_model(model)
    except Exception as error:
        raise ModelRejected(f"the ONNX checker refuses the model: {_short(error)}") from error


def _check_onnx_imports(model: Any) -> None:
    for opset in model.opset_import:
        if opset.domain not in ONNX_IMPORTS:
            raise ModelRejected(f"non-standard operator domain {opset.domain!r}: only the standard ONNX operators "
                                "are allowed")
    if len(model.functions):
        raise ModelRejected("model-local functions are not allowed: export a plain graph")


def _onnx_graphs(graph: Any) -> Iterator[Any]:
    """The graph and every subgraph held in node attributes (refused later, but their data checked first)."""
    yield graph
    for node in graph.node:
        for attribute in node.attribute:
            subgraphs = ([attribute.g] if attribute.HasField("g") else []) + list(attribute.graphs)
            for subgraph in subgraphs:
                yield from _onnx_graphs(subgraph)


def onnx_tensors(model: Any) -> Iterator[Any]:
    """Every tensor of the model: initializers and node attributes, of its graph and subgraphs."""
    for graph in _onnx_graphs(model.graph):
        yield from _graph_tensors(graph)


def _graph_tensors(graph: Any) -> list[Any]:
    tensors = list(graph.initializer) + [s.values for s in graph.sparse_initializer]
    for node in graph.node:
        for attribute in node.attribute:
            tensors += ([attribute.t] if attribute.HasField("t") else []) + list(attribute.tensors)
    return tensors


def refers_to_external_data(tensor: Any) -> bool:
    return tensor.data_location == 1 or len(tensor.external_data) > 0  # TensorProto.EXTERNAL


def _check_onnx_tensors(graph: Any) -> None:
    for tensor in _graph_tensors(graph):
        if refers_to_external_data(tensor):
            raise ModelRejected(f"tensor {tensor.name!r} refers to external data: upload one self-contained "
                                f"file ({SELF_CONTAINED})")


def _check_onnx_node(node: Any) -> None:
    if node.domain not in ONNX_DOMAINS:
        raise ModelRejected(f"operator {node.domain}.{node.op_type} is not a standard ONNX operator")
    if node.op_type not in ONNX_OPS:
        raise ModelRejected(f"operator {node.op_type!r} is not allowed in league models (MLP/CNN operators only)")


# --------------------------------------------------------------------------- TorchScript


def check_torchscript_archive(path: Path) -> None:
    """Before loading: a real TorchScript zip, each of its code files valid TorchScript source that
    defines no method run at load time (parsed, whatever its spelling)."""
    with open(path, "rb") as handle:
        head = handle.read(4)
    if is_pickle(head):
        raise ModelRejected("the file is a Python pickle, not TorchScript; pickles can run any code and are never "
                            "loaded: export with torch.jit.script(model).save(path)")
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
            _check_archive_layout(path, [info.filename for info in infos])
            for info in infos:
                if info.filename.endswith(".py"):
                    _check_torchscript_source(archive, info)
    except zipfile.BadZipFile as error:
        raise ModelRejected("damaged zip archive (truncated?), not a loadable TorchScript file") from error


def _check_archive_layout(path: Path, names: list[str]) -> None:
    if any(name.startswith("/") or ".." in name.split("/") for name in names):
        raise ModelRejected("the archive holds paths outside itself")
    if len(set(names)) != len(names):
        raise ModelRejected("the archive holds two files of the same name")
    if not is_torchscript_layout(names):
        raise ModelRejected(f"{path.suffix or 'the'} file is a torch.save checkpoint (a pickle), not TorchScript: "
                            "export with torch.jit.script(model).save(path)")


def _check_torchscript_source(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    if info.file_size > MAX_CODE_FILE:
        raise ModelRejected(f"TorchScript code file {info.filename} is too large")
    try:
        tree = ast.parse(archive.read(info).decode("utf-8"), filename=info.filename)
    except (UnicodeDecodeError, SyntaxError, ValueError) as error:
        raise ModelRejected(f"{info.filename} is not TorchScript code: {_short(error)}") from error
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in LOAD_TIME_METHODS:
            raise ModelRejected(f"the TorchScript code defines {node.name}, which runs while the file is loaded: "
                                "league models may not (remove it and export again)")


def check_torchscript_graph(module: Any) -> None:
    """After loading (nothing run yet): every operator of every method and hook of the module and
    its submodules, inlined, is allow-listed."""
    for where, graph in _every_graph(module):
        for kind in sorted(_graph_kinds(graph)):
            namespace, _, name = kind.partition("::")
            allowed = TORCH_PRIM_OPS if namespace == "prim" else TORCH_ATEN_OPS if namespace == "aten" else ()
            if name not in allowed:
                raise ModelRejected(f"operator {kind} (in {where}) is not allowed in league models "
                                    "(MLP/CNN operators only)")


def _every_graph(module: Any) -> Iterator[tuple[str, Any]]:
    import torch

    if "forward" not in module._c._method_names():
        raise ModelRejected("the TorchScript module has no forward method")
    for prefix, submodule in module.named_modules():
        owner = prefix or type(module).__name__
        for name in submodule._c._method_names():
            if name in LOAD_TIME_METHODS:
                raise ModelRejected(f"{owner} defines {name}, which runs while a file is loaded")
            yield f"{owner}.{name}", _inlined(torch, submodule._c._get_method(name).graph)
        for hook in [*submodule._c._get_forward_pre_hooks(), *submodule._c._get_forward_hooks()]:
            yield f"a hook of {owner}", _inlined(torch, hook.graph)


def _inlined(torch: Any, graph: Any) -> Any:
    """The graph with every call it makes inlined, so no operator hides in a called function."""
    graph = graph.copy()
    torch._C._jit_pass_inline(graph)
    return graph


def _graph_kinds(graph: Any) -> set[str]:
    kinds = set()
    for node in graph.nodes():
        kinds.add(node.kind())
        for block in node.blocks():
            kinds |= _graph_kinds(block)
    return kinds


def _short(error: BaseException, limit: int = 200) -> str:
    text = " ".join(str(error).split()) or type(error).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."

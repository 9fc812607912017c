"""A model file as the league takes it: one self-contained .onnx or TorchScript file.

`model_kind_of` tells the kind from a name (the checks look at the content); `unsupported` says
what to do with a file of another kind (a Keras .h5, a TensorFlow SavedModel, a checkpoint); and
`read_upload` reads what `league check` checks and `league submit` uploads: the file itself, or
an ONNX model with the weights torch wrote beside it (its external data) packed in.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from league.constants import MODEL_SUFFIXES
from league.validation.checks import SELF_CONTAINED, ModelRejected, onnx_tensors, refers_to_external_data

MB = 1024 * 1024
KERAS_ROUTE = ("convert it to ONNX first, with tf2onnx or Keras' own model.export(path, format='onnx') "
               "(docs/STUDENT_GUIDE.md, \"Keras and TensorFlow\")")
OTHER_FORMATS = {  # suffix -> what it is
    ".h5": "a Keras model", ".hdf5": "a Keras model", ".keras": "a Keras model", ".pb": "a TensorFlow graph",
    ".tflite": "a TensorFlow Lite model", ".ckpt": "a checkpoint", ".pkl": "a Python pickle",
    ".pickle": "a Python pickle", ".safetensors": "a tensor file (weights without the network)",
    ".zip": "an archive",
}


def model_kind_of(filename: str | None) -> str | None:
    """"onnx" or "torchscript" from a file name (the checks look at the content), None if neither."""
    return MODEL_SUFFIXES.get(Path(filename or "").suffix.lower())


def unsupported(name: str) -> str:
    """Why a file of another kind is refused, and what to do instead."""
    suffix = Path(name).suffix.lower()
    what = OTHER_FORMATS.get(suffix)
    advice = KERAS_ROUTE if what and ("Keras" in what or "TensorFlow" in what) else (
        "export the network with torch.onnx.export or torch.jit.script")
    return (f"unsupported file type {suffix or '(none)'!r}{f' ({what})' if what else ''}: the league runs ONNX "
            f"(.onnx) and TorchScript (.pt) files; {advice}")


@dataclass(frozen=True)
class Upload:
    """What is checked and uploaded for a model file."""

    name: str  # the file's name (the server tells the kind from it)
    kind: str  # "onnx" or "torchscript"
    data: bytes  # the file, or the ONNX model with its external data packed in
    packed: tuple[str, ...] = ()  # the side files packed in


def read_upload(path: Path, max_bytes: int) -> Upload:
    """The upload of `path`, or ModelRejected with the reason (an unsupported kind, an empty or
    too large file, external data that is not beside it or too large to pack)."""
    if path.is_dir():
        saved_model = (path / "saved_model.pb").is_file()
        raise ModelRejected(f"{path.name} is a folder{' (a TensorFlow SavedModel)' if saved_model else ''}, not a "
                            f"model file: {KERAS_ROUTE if saved_model else 'give an .onnx or .pt file'}")
    kind, size = model_kind_of(path.name), path.stat().st_size
    if kind is None:
        raise ModelRejected(unsupported(path.name))
    if size == 0:
        raise ModelRejected("the file is empty")
    if size > max_bytes:
        raise ModelRejected(too_large(max_bytes))
    data = path.read_bytes()
    if kind == "onnx":
        return pack_external_data(path, data, max_bytes)
    return Upload(path.name, kind, data)


def too_large(max_bytes: int) -> str:
    return f"file too large: the limit is {max_bytes / MB:g} MB"


def pack_external_data(path: Path, data: bytes, max_bytes: int) -> Upload:
    """The ONNX model `data` (read from `path`) with the tensors it keeps in files beside it read
    into it: one self-contained file, as the league takes it (torch.onnx.export writes
    `model.onnx.data` beside `model.onnx` by default). A model onnx cannot read is left as it is
    (the checks say why)."""
    import onnx

    try:
        model = onnx.load_from_string(data)
    except Exception:  # noqa: BLE001 - not ONNX: the static checks give the reason
        return Upload(path.name, "onnx", data)
    tensors = [tensor for tensor in onnx_tensors(model) if refers_to_external_data(tensor)]
    if not tensors:
        return Upload(path.name, "onnx", data)
    sides, total = set(), len(data)
    for tensor in tensors:
        location, offset, length = _external_slice(path, tensor)
        total += length
        if total > max_bytes:
            raise ModelRejected(f"{too_large(max_bytes)} ({path.name} with its external data packed in is over it)")
        with open(path.parent / location, "rb") as side:
            side.seek(offset)
            tensor.raw_data = side.read(length)
        del tensor.external_data[:]
        tensor.data_location = onnx.TensorProto.DEFAULT
        sides.add(location)
    packed = model.SerializeToString()
    if len(packed) > max_bytes:
        raise ModelRejected(f"{too_large(max_bytes)} ({path.name} with its external data packed in is "
                            f"{len(packed) / MB:.1f} MB)")
    return Upload(path.name, "onnx", packed, tuple(sorted(sides)))


def _external_slice(path: Path, tensor) -> tuple[str, int, int]:
    """(file name, offset, length) of a tensor's external data: a file beside the model, only."""
    info = {entry.key: entry.value for entry in tensor.external_data}
    location = info.get("location", "")
    if not location or Path(location).name != location or location in (".", ".."):
        raise ModelRejected(f"tensor {tensor.name!r} refers to external data at {location!r}, not in a file beside "
                            f"{path.name}: export one self-contained file ({SELF_CONTAINED})")
    side = path.parent / location
    if not side.is_file():
        raise ModelRejected(f"tensor {tensor.name!r} keeps its data in {location}, which is not beside {path.name}: "
                            f"keep the two together, or export one self-contained file ({SELF_CONTAINED})")
    try:
        offset = int(info.get("offset", 0))
        length = int(info["length"]) if "length" in info else side.stat().st_size - offset
    except ValueError as error:
        raise ModelRejected(f"tensor {tensor.name!r} has an invalid external data entry: {error}") from error
    if offset < 0 or length < 0 or offset + length > side.stat().st_size:
        raise ModelRejected(f"tensor {tensor.name!r} refers to bytes {offset}..{offset + length} of {location}, "
                            f"which has {side.stat().st_size}: the model and its data do not match; export again")
    return location, offset, length

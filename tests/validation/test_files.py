"""A model file as the league takes it: its kind from its name, what to do with other kinds, and
an ONNX model's external data packed into one file (only from files beside it, within the limit)."""
from __future__ import annotations

import numpy as np
import onnx
import pytest

from league import testing as mf
from league.agents import load_agent
from league.validation.checks import ModelRejected, check_onnx
from league.validation.files import model_kind_of, read_upload

MB = 1024 * 1024


@pytest.mark.parametrize("name, kind", [("a.onnx", "onnx"), ("A.PT", "torchscript"), ("b.pth", "torchscript"),
                                        ("c.py", None), ("noext", None), (None, None)])
def test_model_kind_from_the_file_name(name, kind):
    assert model_kind_of(name) == kind


def test_keras_files_and_saved_models_get_the_route_to_onnx(tmp_path):
    keras = tmp_path / "actor.keras"
    keras.write_bytes(b"PK\x03\x04")
    saved_model = tmp_path / "ddpg_actor_model_car"
    saved_model.mkdir()
    (saved_model / "saved_model.pb").write_bytes(b"\x08\x01")
    with pytest.raises(ModelRejected, match=r"^unsupported file type '.keras' \(a Keras model\): .* convert it to "
                                            r"ONNX first, with tf2onnx"):
        read_upload(keras, MB)
    with pytest.raises(ModelRejected, match=r"^ddpg_actor_model_car is a folder \(a TensorFlow SavedModel\), not "
                                            r"a model file: convert it to ONNX first"):
        read_upload(saved_model, MB)


def test_external_data_beside_the_model_is_packed_into_one_file(tmp_path):
    model = mf.onnx_external_data(tmp_path / "external.onnx")
    with pytest.raises(ModelRejected, match="refers to external data.*external_data=False"):
        check_onnx(model)  # as the server sees the file alone
    upload = read_upload(model, MB)
    assert (upload.name, upload.kind, upload.packed) == ("external.onnx", "onnx", ("weights.bin",))
    packed = tmp_path / "packed" / "external.onnx"
    packed.parent.mkdir()
    packed.write_bytes(upload.data)
    check_onnx(packed)  # self-contained now
    obs = np.random.default_rng(0).uniform(-1, 1, (8, 5)).astype(np.float32)
    np.testing.assert_array_equal(load_agent(packed)(obs), load_agent(model)(obs))


def test_a_model_without_external_data_is_uploaded_as_it_is(tmp_path):
    model = mf.onnx_mlp(tmp_path / "plain.onnx")
    assert read_upload(model, MB).data == model.read_bytes()


def test_external_data_is_read_only_from_files_beside_the_model_and_within_the_limit(tmp_path):
    model = mf.onnx_external_data(tmp_path / "external.onnx")
    with pytest.raises(ModelRejected, match=r"^file too large: the limit is 0.00976562 MB \(external.onnx with its "
                                            r"external data packed in is over it\)"):
        read_upload(model, 10 * 1024)
    (tmp_path / "weights.bin").rename(tmp_path / "elsewhere.bin")
    with pytest.raises(ModelRejected, match=r"keeps its data in weights.bin, which is not beside external.onnx: "
                                            r".*external_data=False"):
        read_upload(model, MB)
    for location in ("../weights.bin", "/etc/passwd", "sub/weights.bin"):
        _point_external_data(model, location)
        with pytest.raises(ModelRejected, match=f"refers to external data at '{location}', not in a file beside"):
            read_upload(model, MB)


def test_external_data_past_the_end_of_its_file_is_refused(tmp_path):
    model = mf.onnx_external_data(tmp_path / "external.onnx")
    _point_external_data(model, "weights.bin", offset=10**6)
    with pytest.raises(ModelRejected, match=r"refers to bytes 1000000\.\.\d+ of weights.bin, which has \d+: the "
                                            r"model and its data do not match"):
        read_upload(model, MB)


def _point_external_data(path, location: str, offset: int | None = None) -> None:
    model = onnx.load(str(path), load_external_data=False)
    tensor = next(t for t in model.graph.initializer if len(t.external_data))
    for entry in tensor.external_data:
        if entry.key == "location":
            entry.value = location
        elif entry.key == "offset" and offset is not None:
            entry.value = str(offset)
    if offset is not None and not any(entry.key == "offset" for entry in tensor.external_data):
        tensor.external_data.add(key="offset", value=str(offset))
    path.write_bytes(model.SerializeToString())

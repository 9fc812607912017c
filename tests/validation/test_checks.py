"""The static checks of ONNX graphs, on their structure (the sandbox's tests run them on hostile
files through the server: tests/server/sandbox/)."""
from __future__ import annotations

import onnx
import pytest
from onnx import TensorProto, helper

from league.validation.checks import ModelRejected, check_onnx


def _model(path, nodes, opsets):
    value = helper.make_tensor_value_info
    graph = helper.make_graph(nodes, "policy", [value("obs", TensorProto.FLOAT, [None, 5])],
                              [value("actions", TensorProto.FLOAT, [None, 5])])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid(d, v) for d, v in opsets]), str(path))
    return path


def test_a_declared_onnx_ml_operator_set_is_accepted_but_not_its_operators(tmp_path):
    """tf2onnx and Keras declare ai.onnx.ml in every model they write; what runs must still be standard."""
    declared = _model(tmp_path / "keras.onnx", [helper.make_node("Tanh", ["obs"], ["actions"])],
                      [("", 15), ("ai.onnx.ml", 2)])
    check_onnx(declared)
    used = _model(tmp_path / "ml.onnx", [helper.make_node("Normalizer", ["obs"], ["actions"], domain="ai.onnx.ml")],
                  [("", 15), ("ai.onnx.ml", 2)])
    with pytest.raises(ModelRejected, match=r"^operator ai.onnx.ml.Normalizer is not a standard ONNX operator"):
        check_onnx(used)
    custom = _model(tmp_path / "custom.onnx", [helper.make_node("Tanh", ["obs"], ["actions"])],
                    [("", 15), ("com.example", 1)])
    with pytest.raises(ModelRejected, match=r"^non-standard operator domain 'com.example'"):
        check_onnx(custom)

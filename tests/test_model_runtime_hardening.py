"""Hostile or damaged TF.js model files are refused on load with one line naming the file and
the fault (``ModelFileError``, a ValueError), quickly and before any large allocation:
bad JSON, unknown ops, weight shapes that do not match the shards, absurd or negative shapes,
truncated or missing shards, shard names outside the folder, non-finite quantisation scales,
NaN weights, cycles, dangling references, malformed attributes, and ops that would make an
absurdly large tensor from the file's constants. Intact files still load and run."""

from __future__ import annotations

import json
import shutil
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import torch
from model_runtime_files import (
    attr_ints,
    attr_string,
    const,
    conv_relu_model,
    node,
    placeholder,
    read_document,
    reference_conv_relu,
    write_document,
    write_model,
)

from hkpd.model_runtime import GraphModel, ModelFileError
from hkpd.model_runtime import graph_file as graph_file_module
from hkpd.model_runtime.shipped import human_model_path


def _refused(path: Path, *words: str) -> str:
    """Load ``path``; it must raise one ModelFileError line naming it and ``words``, within a
    second and allocating under 32 MB of Python/numpy memory."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        with pytest.raises(ModelFileError) as caught:
            GraphModel.load(path)
        elapsed = time.perf_counter() - start
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(caught.value)
    assert isinstance(caught.value, ValueError)
    assert "\n" not in message and str(path) in message, message
    for word in words:
        assert word in message, (word, message)
    assert elapsed < 1.0, elapsed
    assert peak < 32 * 2**20, peak
    return message


def test_an_intact_small_model_loads_and_runs(tmp_path) -> None:
    path = conv_relu_model(tmp_path)
    model = GraphModel.load(path)
    x = torch.randn(3, 5, 5, 2, generator=torch.Generator().manual_seed(1))
    out = model.run({"x": x})["out"]
    weights = {spec["name"]: None for spec in read_document(path)["weightsManifest"][0]["weights"]}
    assert set(weights) == {"kernel", "bias"}
    data = np.frombuffer(path.with_suffix(".bin").read_bytes()[: 3 * 3 * 2 * 4 * 2], "<f2")
    kernel = data.astype(np.float64).reshape(3, 3, 2, 4)
    bias = np.frombuffer(path.with_suffix(".bin").read_bytes()[3 * 3 * 2 * 4 * 2 :], "<f4")
    expected = reference_conv_relu(x.numpy(), kernel, bias)
    assert out.shape == (3, 3, 3, 4)
    np.testing.assert_allclose(out.numpy(), expected, atol=1e-5)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('{"format": "graph-model", "modelTopology": {"node": [', ("not valid JSON",)),
        ("[1, 2, 3]", ("not an object",)),
        ('{"format": "layers-model"}', ("layers-model", "graph-model")),
        ('{"modelTopology": {"node": []}}', ("weightsManifest",)),
        ('{"modelTopology": {}, "weightsManifest": []}', ("'node'",)),
        ("\xff\xfe garbage", ("not valid JSON",)),
    ],
)
def test_bad_json_is_refused(tmp_path, text, words) -> None:
    path = tmp_path / "model.json"
    path.write_bytes(text.encode("latin-1"))
    _refused(path, *words)


def test_an_oversized_json_is_refused_before_parsing(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(graph_file_module, "MAX_JSON_BYTES", 1000)
    path = tmp_path / "model.json"
    path.write_text(json.dumps({"padding": "x" * 5000}))
    _refused(path, "larger than 1,000 bytes")


def test_an_unknown_op_is_refused_naming_op_and_node(tmp_path) -> None:
    nodes = [placeholder("x", [1, 4]), node("strange", "FancyNewOp", ["x"])]
    message = _refused(write_model(tmp_path, nodes, {}), "'FancyNewOp'", "'strange'")
    assert "does not implement" in message


def _with_weight_spec(tmp_path: Path, **changes) -> Path:
    path = conv_relu_model(tmp_path)
    document = read_document(path)
    document["weightsManifest"][0]["weights"][1].update(changes)
    write_document(path, document)
    return path


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"shape": [5]}, ("shards hold", "declare")),
        ({"shape": [3]}, ("shards hold", "declare")),
        ({"shape": [2**20, 2**20]}, ("absurd shape",)),
        ({"shape": [4, -1]}, ("negative dimension",)),
        ({"shape": "4"}, ("malformed shape",)),
        ({"shape": [4.5]}, ("malformed shape",)),
        ({"dtype": "string"}, ("unsupported dtype",)),
        ({"dtype": "complex64"}, ("unsupported dtype",)),
        ({"quantization": {"dtype": "int4"}}, ("unsupported quantisation",)),
        ({"quantization": {"dtype": "uint8", "scale": float("nan"), "min": 0}}, ("non-finite",)),
        ({"quantization": {"dtype": "uint8", "scale": float("inf"), "min": 0}}, ("non-finite",)),
        ({"quantization": {"dtype": "uint16", "min": 0}}, ("without a scale",)),
    ],
)
def test_weight_specs_that_do_not_fit_are_refused(tmp_path, changes, words) -> None:
    _refused(_with_weight_spec(tmp_path, **changes), *words)


def test_truncated_missing_and_padded_shards_are_refused(tmp_path) -> None:
    path = conv_relu_model(tmp_path)
    shard = path.with_suffix(".bin")
    data = shard.read_bytes()
    shard.write_bytes(data[:-3])
    _refused(path, "shards hold", "truncated")
    shard.write_bytes(data + b"\0" * 8)
    _refused(path, "shards hold")
    shard.unlink()
    _refused(path, "model.bin is missing")


@pytest.mark.parametrize("name", ["../model.bin", "/etc/passwd", "sub/model.bin", "..", 7])
def test_shard_names_outside_the_folder_are_refused(tmp_path, name) -> None:
    path = conv_relu_model(tmp_path)
    document = read_document(path)
    document["weightsManifest"][0]["paths"] = [name]
    write_document(path, document)
    _refused(path, "not a plain file name")


def test_nan_weights_are_refused(tmp_path) -> None:
    nodes = [placeholder("x", [2]), const("w"), node("out", "Add", ["x", "w"])]
    path = write_model(tmp_path, nodes, {"w": np.array([1.0, np.nan], np.float32)})
    _refused(path, "'w'", "NaN")


@pytest.mark.parametrize(
    ("nodes", "words"),
    [
        (
            [
                placeholder("x", [2]),
                node("a", "Add", ["x", "b"]),
                node("b", "Relu", ["a"]),
                node("out", "Relu", ["b"]),
            ],
            ("cycle",),
        ),
        ([placeholder("x", [2]), node("a", "Relu", ["missing"])], ("'missing'", "no node")),
        ([placeholder("x", [2]), const("c"), node("a", "Add", ["x", "c"])], ("without a weight",)),
        ([placeholder("x", [2]), placeholder("x", [2])], ("two nodes",)),
        (
            [placeholder("x", [2]), const("k"), node("a", "Add", ["x", "k:3"])],
            ("'k:3'", "no output"),
        ),
        ([{"op": "Relu"}], ("'name'",)),
        ([placeholder("x", [2]), node("a", "Relu", ["x", 5])], ("not a name",)),
    ],
)
def test_malformed_graphs_are_refused(tmp_path, nodes, words) -> None:
    weights = {"k": np.zeros(2, np.float32)} if const("k") in nodes else {}
    _refused(write_model(tmp_path, nodes, weights), *words)


def _conv_node(**overrides) -> list[dict]:
    attributes = {
        "strides": attr_ints([1, 1, 1, 1]),
        "padding": attr_string("SAME"),
        "dilations": attr_ints([1, 1, 1, 1]),
    }
    attributes.update(overrides)
    return [
        placeholder("x", [1, 4, 4, 2]),
        const("k"),
        node("c", "Conv2D", ["x", "k"], **attributes),
    ]


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        ({"padding": attr_string("CIRCULAR")}, ("'c'", "padding 'CIRCULAR'")),
        ({"strides": attr_ints([1, 0, 1, 1])}, ("strides",)),
        ({"strides": attr_ints([2, 1, 1, 1])}, ("strides",)),
        ({"data_format": attr_string("NCHW")}, ("NCHW",)),
        ({"padding": {"s": "%%%not base64"}}, ("'padding' is malformed",)),
        ({"strides": {"list": {"i": ["one"]}}}, ("'strides' is malformed",)),
        ({"fused_ops": {"list": {"s": [attr_string("Softsign")["s"]]}}}, ("fused ops",)),
    ],
)
def test_malformed_attributes_are_refused_naming_the_node(tmp_path, overrides, words) -> None:
    kernel = np.ones((3, 3, 2, 2), np.float32)
    _refused(write_model(tmp_path, _conv_node(**overrides), {"k": kernel}), *words)


def test_constants_that_would_make_an_absurd_tensor_are_refused(tmp_path) -> None:
    """A SparseToDense (or Fill, Pad) whose constant shape asks for 2^40 elements is refused
    while folding, before anything is allocated."""
    nodes = [
        placeholder("x", [1]),
        const("indices", "DT_INT32"),
        const("shape", "DT_INT32"),
        const("values", "DT_INT32"),
        const("default", "DT_INT32"),
        node("dense", "SparseToDense", ["indices", "shape", "values", "default"]),
        node("out", "Add", ["x", "dense"]),
    ]
    weights = {
        "indices": np.zeros((0, 2), np.int32),
        "shape": np.array([2**20, 2**20], np.int32),
        "values": np.zeros(0, np.int32),
        "default": np.array(0, np.int32),
    }
    _refused(write_model(tmp_path, nodes, weights), "'dense'", "elements")


def test_broadcasting_to_an_absurd_size_is_refused(tmp_path) -> None:
    nodes = [placeholder("x", [1]), const("a"), const("b"), node("out", "Mul", ["a", "b"])]
    weights = {"a": np.ones((2**15, 1), np.float32), "b": np.ones((1, 2**15), np.float32)}
    _refused(write_model(tmp_path, nodes, weights), "'out'", "elements")


def _damaged_copy(tmp_path: Path, damage) -> Path:
    source = human_model_path("faceres")
    for suffix in (".json", ".bin"):
        shutil.copy(source.with_suffix(suffix), tmp_path / f"faceres{suffix}")
    damage(tmp_path / "faceres.json", tmp_path / "faceres.bin")
    return tmp_path / "faceres.json"


def _truncate(json_path: Path, shard: Path) -> None:
    shard.write_bytes(shard.read_bytes()[: shard.stat().st_size // 3])


def _cut_json(json_path: Path, shard: Path) -> None:
    json_path.write_bytes(json_path.read_bytes()[:5000])


def _git_lfs_pointer(json_path: Path, shard: Path) -> None:
    shard.write_text("version https://git-lfs.github.com/spec/v1\noid sha256:0\nsize 6978814\n")


def _grow_a_weight(json_path: Path, shard: Path) -> None:
    document = read_document(json_path)
    document["weightsManifest"][0]["weights"][0]["shape"][0] *= 2
    write_document(json_path, document)


def _rename_an_op(json_path: Path, shard: Path) -> None:
    document = read_document(json_path)
    document["modelTopology"]["node"][5]["op"] = "Conv3D"
    write_document(json_path, document)


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        (_truncate, ("shards hold",)),
        (_cut_json, ("not valid JSON",)),
        (_git_lfs_pointer, ("shards hold",)),
        (_grow_a_weight, ("shards hold",)),
        (_rename_an_op, ("'Conv3D'",)),
    ],
)
def test_a_damaged_copy_of_a_shipped_model_is_refused(tmp_path, damage, words) -> None:
    _refused(_damaged_copy(tmp_path, damage), *words)


def test_a_missing_model_file_is_file_not_found(tmp_path) -> None:
    with pytest.raises(FileNotFoundError):
        GraphModel.load(tmp_path / "absent.json")


def test_inputs_of_the_wrong_kind_or_shape_are_refused_clearly(tmp_path) -> None:
    model = GraphModel.load(conv_relu_model(tmp_path))
    with pytest.raises(ValueError, match=r"must have the shape \[-1, 5, 5, 2\]"):
        model.run({"x": torch.zeros(1, 5, 6, 2)})
    with pytest.raises(ValueError, match="must be floating-point"):
        model.run({"x": torch.zeros(1, 5, 5, 2, dtype=torch.int32)})
    with pytest.raises(ValueError, match=r"unknown \['y'\], missing \['x'\]"):
        model.run({"y": torch.zeros(1, 5, 5, 2)})
    with pytest.raises(KeyError, match="no output"):
        model.run({"x": torch.zeros(1, 5, 5, 2)}, ["nowhere"])


def test_a_gather_into_an_absurd_size_is_refused(tmp_path) -> None:
    nodes = [
        placeholder("x", [1]),
        const("params"),
        const("indices", "DT_INT32"),
        const("axis", "DT_INT32"),
        node("out", "GatherV2", ["params", "indices", "axis"]),
    ]
    weights = {
        "params": np.ones((1, 2**12), np.float32),
        "indices": np.zeros(2**18, np.int32),
        "axis": np.array(0, np.int32),
    }
    _refused(write_model(tmp_path, nodes, weights), "'out'", "elements")


@pytest.mark.parametrize("op", ["MatMul", "ConcatV2", "Pack"])
def test_products_and_concatenations_into_an_absurd_size_are_refused(tmp_path, op) -> None:
    nodes = [placeholder("x", [1]), const("a"), const("b"), const("axis", "DT_INT32")]
    if op == "MatMul":
        nodes.append(node("out", op, ["a", "b"]))
    elif op == "ConcatV2":
        nodes.append(node("out", op, ["a"] * 300 + ["axis"]))
    else:
        nodes.append(node("out", op, ["a"] * 300, axis={"i": "0"}))
    weights = {
        "a": np.ones((2**20, 1), np.float32),
        "b": np.ones((1, 2**9), np.float32),
        "axis": np.array(0, np.int32),
    }
    _refused(write_model(tmp_path, nodes, weights), "'out'", "elements")


def test_a_convolution_with_an_absurd_output_is_refused_when_run(tmp_path) -> None:
    """The output's size depends on the input: checked before convolving."""
    nodes = [
        placeholder("x", [-1, -1, -1, 1]),
        const("k"),
        node(
            "out",
            "Conv2D",
            ["x", "k"],
            strides=attr_ints([1, 1, 1, 1]),
            padding=attr_string("VALID"),
        ),
    ]
    model = GraphModel.load(
        write_model(tmp_path, nodes, {"k": np.ones((1, 1, 1, 2**12), np.float32)})
    )
    with pytest.raises(ValueError, match="elements"):
        model.run({"x": torch.zeros(1, 256, 512, 1)})

"""Writing small TF.js graph models for the runtime's tests (tests/test_model_runtime_*.py)."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import numpy as np


def attr_ints(values: list[int]) -> dict:
    return {"list": {"i": [str(value) for value in values]}}


def attr_string(text: str) -> dict:
    return {"s": base64.b64encode(text.encode()).decode()}


def placeholder(name: str, shape: list[int], dtype: str = "DT_FLOAT") -> dict:
    return {
        "name": name,
        "op": "Placeholder",
        "attr": {
            "dtype": {"type": dtype},
            "shape": {"shape": {"dim": [{"size": str(s)} for s in shape]}},
        },
    }


def const(name: str, dtype: str = "DT_FLOAT") -> dict:
    return {
        "name": name,
        "op": "Const",
        "attr": {"dtype": {"type": dtype}, "value": {"tensor": {}}},
    }


def node(name: str, op: str, inputs: list[str], **attributes: Any) -> dict:
    return {"name": name, "op": op, "input": inputs, "attr": attributes}


def weight_bytes(array: np.ndarray, quantization: dict | None = None) -> bytes:
    """The shard bytes of ``array`` (float32/int32/bool, or float16 if so quantised)."""
    if quantization and quantization["dtype"] == "float16":
        return array.astype("<f2").tobytes()
    if array.dtype == np.bool_:
        return array.astype(np.uint8).tobytes()
    return array.astype("<f4" if array.dtype.kind == "f" else "<i4").tobytes()


def write_model(
    folder: Path,
    nodes: list[dict],
    weights: dict[str, np.ndarray],
    *,
    quantization: dict[str, dict] | None = None,
    raw_weights: dict[str, bytes] | None = None,
    signature: dict | None = None,
    name: str = "model",
) -> Path:
    """Write ``name.json`` and ``name.bin`` into ``folder``; returns the json's path.

    ``quantization`` maps weight names to their manifest quantisation entry; ``raw_weights``
    gives a weight's shard bytes directly (for uint8/uint16 values).
    """
    quantization = quantization or {}
    raw_weights = raw_weights or {}
    specs, chunks = [], []
    for weight_name, array in weights.items():
        dtype = {"f": "float32", "i": "int32", "b": "bool"}[np.asarray(array).dtype.kind]
        spec = {"name": weight_name, "shape": list(np.shape(array)), "dtype": dtype}
        if weight_name in quantization:
            spec["quantization"] = quantization[weight_name]
        specs.append(spec)
        data = raw_weights.get(weight_name)
        chunks.append(
            data if data is not None else weight_bytes(np.asarray(array), spec.get("quantization"))
        )
    (folder / f"{name}.bin").write_bytes(b"".join(chunks))
    document = {
        "format": "graph-model",
        "modelTopology": {"node": nodes},
        "weightsManifest": [{"paths": [f"{name}.bin"], "weights": specs}],
    }
    if signature is not None:
        document["signature"] = signature
    path = folder / f"{name}.json"
    path.write_text(json.dumps(document))
    return path


def conv_relu_model(folder: Path) -> Path:
    """``x (N, 5, 5, 2) -> relu(conv2d(x, 3×3, stride 2, SAME) + bias)``, output ``out``;
    a float16-quantised kernel and a float32 bias."""
    generator = np.random.default_rng(0)
    kernel = generator.standard_normal((3, 3, 2, 4)).astype(np.float16).astype(np.float32)
    bias = generator.standard_normal(4).astype(np.float32)
    nodes = [
        placeholder("x", [-1, 5, 5, 2]),
        const("kernel"),
        const("bias"),
        node(
            "out",
            "_FusedConv2D",
            ["x", "kernel", "bias"],
            strides=attr_ints([1, 2, 2, 1]),
            padding=attr_string("SAME"),
            data_format=attr_string("NHWC"),
            dilations=attr_ints([1, 1, 1, 1]),
            fused_ops={"list": {"s": [attr_string("BiasAdd")["s"], attr_string("Relu")["s"]]}},
            num_args={"i": "1"},
        ),
    ]
    return write_model(
        folder,
        nodes,
        {"kernel": kernel, "bias": bias},
        quantization={"kernel": {"dtype": "float16", "original_dtype": "float32"}},
    )


def reference_conv_relu(x: np.ndarray, kernel: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """The conv_relu_model's output by plain loops (float64): TF's SAME with stride 2 on 5
    pixels pads 1 before and 1 after."""
    padded = np.pad(x.astype(np.float64), ((0, 0), (1, 1), (1, 1), (0, 0)))
    out = np.zeros((x.shape[0], 3, 3, kernel.shape[3]))
    for row in range(3):
        for column in range(3):
            window = padded[:, 2 * row : 2 * row + 3, 2 * column : 2 * column + 3, :]
            out[:, row, column] = np.einsum("nhwc,hwco->no", window, kernel)
    return np.maximum(out + bias, 0.0)


def read_document(path: Path) -> dict:
    return json.loads(path.read_text())


def write_document(path: Path, document: dict) -> None:
    path.write_text(json.dumps(document))

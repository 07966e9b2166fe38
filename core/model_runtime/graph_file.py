"""Reading a TF.js graph model (``model.json`` and its weight shards) into plain records.

The format is TensorFlow.js's "graph-model": ``model.json`` holds the graph
(``modelTopology.node``: TensorFlow ``NodeDef``s as JSON), an optional ``signature`` (the named
inputs and outputs) and a ``weightsManifest`` (groups of weight specs and the shard files that
hold their bytes, concatenated in order). Weights are float32, int32 or bool, optionally
quantised: ``float16`` (float32 weights stored as IEEE halves) or ``uint8``/``uint16`` affine
(value = q·scale + min; int32 weights rounded as JavaScript's ``Math.round``).

Everything is checked before any large allocation: the JSON's size, each weight's shape (no
negative dimensions, at most :data:`MAX_TENSOR_ELEMENTS` elements), the shard files' names
(plain names beside ``model.json``) and that their sizes add up exactly to what the specs
declare. A file that fails any check raises :class:`ModelFileError` naming it and the fault.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

MAX_TENSOR_ELEMENTS = 2**28
"""Most elements one weight (or one declared tensor shape) may have: 1 GiB of float32."""

MAX_WEIGHT_BYTES = 2**30
"""Most bytes all shards of one model may hold together."""

MAX_JSON_BYTES = 64 * 2**20
"""Largest ``model.json`` read (the package's largest is ~0.3 MB)."""

MAX_NODES = 200_000
"""Most nodes one graph may have."""

_VALUE_BYTES = {"float32": 4, "int32": 4, "bool": 1}
_QUANTISED_BYTES = {"float16": 2, "uint8": 1, "uint16": 2}
_SHARD_NAME = re.compile(r"[A-Za-z0-9._-]+")


class ModelFileError(ValueError):
    """A model file is damaged, hostile or uses something this runtime does not implement; the
    message (one line) names the file and what is wrong."""


@dataclass(frozen=True)
class GraphNode:
    """One node of the graph.

    Attributes:
        name: the node's unique name.
        op: its TensorFlow op type (``"Conv2D"``, ``"_FusedConv2D"``, ...).
        inputs: references to other nodes' outputs, ``"name"`` or ``"name:k"`` (control
            inputs ``"^name"`` are dropped: execution order follows the data).
        attributes: the decoded attributes (strings, ints, floats, bools, dtype names such as
            ``"DT_FLOAT"``, shapes as tuples with -1 for unknown sizes, and lists of those).
    """

    name: str
    op: str
    inputs: tuple[str, ...]
    attributes: dict[str, Any]


@dataclass(frozen=True)
class TensorSignature:
    """One named input or output of the model: its node reference, dtype name and shape
    (``-1`` where the size is free; None if the rank is unknown)."""

    name: str
    dtype: str
    shape: tuple[int, ...] | None


@dataclass(frozen=True)
class GraphFile:
    """A checked, dequantised TF.js graph model.

    Attributes:
        path: the ``model.json`` it was read from.
        nodes: the graph's nodes in file order.
        weights: each weight by name, float32 / int32 / bool numpy arrays of the declared shape.
        inputs: the signature's inputs (empty if the file has no signature).
        outputs: the signature's outputs (empty if the file has no signature).
    """

    path: Path
    nodes: tuple[GraphNode, ...]
    weights: dict[str, np.ndarray]
    inputs: tuple[TensorSignature, ...]
    outputs: tuple[TensorSignature, ...]


def read_graph_file(path: str | Path) -> GraphFile:
    """Read and check ``model.json`` and the weight shards beside it.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ModelFileError: bad JSON, not a graph model, malformed nodes or weight specs, absurd
            shapes, shard names outside the folder, missing or wrongly sized shards.
    """
    path = Path(path)
    document = _read_json(path)
    topology = _field(path, document, "modelTopology", dict)
    raw_nodes = _field(path, topology, "node", list)
    if len(raw_nodes) > MAX_NODES:
        raise ModelFileError(f"{path}: {len(raw_nodes):,} nodes, more than {MAX_NODES:,}")
    nodes = tuple(_parse_node(path, raw) for raw in raw_nodes)
    names = [node.name for node in nodes]
    if len(set(names)) != len(names):
        duplicate = next(name for name in names if names.count(name) > 1)
        raise ModelFileError(f"{path}: two nodes are named {duplicate!r}")
    manifest = _field(path, document, "weightsManifest", list)
    weights = _read_weights(path, manifest)
    signature = document.get("signature") or {}
    if not isinstance(signature, dict):
        raise ModelFileError(f"{path}: 'signature' is not an object")
    return GraphFile(
        path=path,
        nodes=nodes,
        weights=weights,
        inputs=_parse_signature(path, signature, "inputs"),
        outputs=_parse_signature(path, signature, "outputs"),
    )


def _read_json(path: Path) -> dict[str, Any]:
    """``model.json``'s top-level object, its size bounded; refuses layers models."""
    with path.open("rb") as file:
        size = os.fstat(file.fileno()).st_size
        text = file.read(min(size, MAX_JSON_BYTES) + 1)
    if len(text) > MAX_JSON_BYTES:
        raise ModelFileError(f"{path}: larger than {MAX_JSON_BYTES:,} bytes, not a model.json")
    try:
        document = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as error:
        raise ModelFileError(f"{path}: not valid JSON ({error})") from None
    if not isinstance(document, dict):
        raise ModelFileError(f"{path}: the JSON is not an object")
    model_format = document.get("format", "graph-model")
    if model_format != "graph-model":
        raise ModelFileError(f"{path}: format {model_format!r}, only 'graph-model' is supported")
    return document


def _field(path: Path, record: dict[str, Any], key: str, kind: type) -> Any:
    """``record[key]``, which must exist and be of ``kind``."""
    value = record.get(key)
    if not isinstance(value, kind):
        raise ModelFileError(f"{path}: {key!r} is missing or not a {kind.__name__}")
    return value


def _parse_node(path: Path, raw: Any) -> GraphNode:
    """One ``NodeDef`` from its JSON."""
    if not isinstance(raw, dict) or not isinstance(raw.get("name"), str):
        raise ModelFileError(f"{path}: a node is not an object with a 'name'")
    name = raw["name"]
    op = raw.get("op")
    inputs = raw.get("input", [])
    if not isinstance(op, str) or not isinstance(inputs, list):
        raise ModelFileError(f"{path}: node {name!r} has no op or a malformed input list")
    if not all(isinstance(item, str) for item in inputs):
        raise ModelFileError(f"{path}: node {name!r} has an input that is not a name")
    attributes = raw.get("attr", {})
    if not isinstance(attributes, dict):
        raise ModelFileError(f"{path}: node {name!r} has malformed attributes")
    decoded = {key: _attribute(path, name, key, value) for key, value in attributes.items()}
    data_inputs = tuple(item for item in inputs if not item.startswith("^"))
    return GraphNode(name=name, op=op, inputs=data_inputs, attributes=decoded)


def _attribute(path: Path, node: str, key: str, value: Any) -> Any:
    """One ``AttrValue`` decoded to a Python value (see :class:`GraphNode`)."""
    try:
        if not isinstance(value, dict):
            raise TypeError("not an object")
        if "list" in value:
            items = value["list"]
            if not isinstance(items, dict):
                raise TypeError("malformed list")
            kind = next((k for k, v in items.items() if isinstance(v, list) and v), None)
            return [] if kind is None else [_scalar(kind, item) for item in items[kind]]
        for kind in ("s", "i", "f", "b", "type", "shape"):
            if kind in value:
                return _scalar(kind, value[kind])
        return None  # tensors (Const values come from the weights), functions
    except (TypeError, ValueError, binascii.Error, UnicodeDecodeError) as error:
        raise ModelFileError(
            f"{path}: node {node!r}: attribute {key!r} is malformed ({error})"
        ) from None


def _scalar(kind: str, raw: Any) -> Any:
    """One attribute scalar of ``kind`` (``s``, ``i``, ``f``, ``b``, ``type``, ``shape``)."""
    if kind == "s":
        return base64.b64decode(raw, validate=True).decode()
    if kind == "i":
        if isinstance(raw, bool) or not isinstance(raw, str | int):
            raise TypeError(f"integer expected, got {raw!r}")
        return int(raw)
    if kind == "f":
        if isinstance(raw, str) and raw in ("NaN", "Infinity", "-Infinity"):
            return float(raw.replace("Infinity", "inf"))
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise TypeError(f"number expected, got {raw!r}")
        return float(raw)
    if kind == "b":
        if not isinstance(raw, bool):
            raise TypeError(f"boolean expected, got {raw!r}")
        return raw
    if kind == "type":
        if not isinstance(raw, str):
            raise TypeError(f"dtype name expected, got {raw!r}")
        return raw
    if kind == "shape":
        return _shape_attribute(raw)
    raise TypeError(f"unknown attribute kind {kind!r}")


def _shape_attribute(raw: Any) -> tuple[int, ...] | None:
    """A ``TensorShapeProto`` as a tuple (-1: unknown size), None if its rank is unknown."""
    if not isinstance(raw, dict):
        raise TypeError("malformed shape")
    if raw.get("unknownRank"):
        return None
    dims = raw.get("dim", [])
    if not isinstance(dims, list) or len(dims) > 32:
        raise TypeError("malformed shape")
    sizes = tuple(int(dim.get("size", -1)) if isinstance(dim, dict) else -2 for dim in dims)
    if any(size < -1 or size > MAX_TENSOR_ELEMENTS for size in sizes):
        raise ValueError(f"absurd shape {sizes}")
    return sizes


def _parse_signature(path: Path, signature: dict, key: str) -> tuple[TensorSignature, ...]:
    """The signature's ``inputs`` or ``outputs``, in file order."""
    entries = signature.get(key) or {}
    if not isinstance(entries, dict):
        raise ModelFileError(f"{path}: signature {key!r} is not an object")
    parsed = []
    for label, entry in entries.items():
        if not isinstance(entry, dict):
            raise ModelFileError(f"{path}: signature {key} {label!r} is not an object")
        name = entry.get("name", label)
        dtype = entry.get("dtype", "DT_FLOAT")
        if not isinstance(name, str) or not isinstance(dtype, str):
            raise ModelFileError(f"{path}: signature {key} {label!r} is malformed")
        try:
            shape = _shape_attribute(entry.get("tensorShape", {"unknownRank": True}))
        except (TypeError, ValueError) as error:
            raise ModelFileError(f"{path}: signature {key} {label!r}: {error}") from None
        parsed.append(TensorSignature(name=name, dtype=dtype, shape=shape))
    return tuple(parsed)


@dataclass(frozen=True)
class _WeightSpec:
    """One entry of the weights manifest, checked: name, shape, target dtype, the stored
    dtype (``quantised`` or the target), the affine scale/min (uint8/uint16) and byte count."""

    name: str
    shape: tuple[int, ...]
    dtype: str
    stored: str
    scale: float
    offset: float
    byte_count: int


def _read_weights(path: Path, manifest: list) -> dict[str, np.ndarray]:
    """Every weight of the manifest, decoded from the shards beside ``path``."""
    specs: list[_WeightSpec] = []
    shard_paths: list[Path] = []
    for group in manifest:
        if not isinstance(group, dict):
            raise ModelFileError(f"{path}: a weightsManifest group is not an object")
        paths = _field(path, group, "paths", list)
        shard_paths += [_shard_path(path, name) for name in paths]
        specs += [_weight_spec(path, raw) for raw in _field(path, group, "weights", list)]
    expected = sum(spec.byte_count for spec in specs)
    if expected > MAX_WEIGHT_BYTES:
        raise ModelFileError(f"{path}: the weights declare {expected:,} bytes, too many")
    data = _read_shards(path, shard_paths, expected)
    weights: dict[str, np.ndarray] = {}
    offset = 0
    for spec in specs:
        if spec.name in weights:
            raise ModelFileError(f"{path}: the weight {spec.name!r} is declared twice")
        weights[spec.name] = _decode(path, spec, data[offset : offset + spec.byte_count])
        offset += spec.byte_count
    return weights


def _shard_path(path: Path, name: Any) -> Path:
    """A shard's path: a plain file name beside ``model.json`` (no folders, no ``..``)."""
    if not isinstance(name, str) or not _SHARD_NAME.fullmatch(name) or set(name) == {"."}:
        raise ModelFileError(f"{path}: the shard name {name!r} is not a plain file name")
    return path.parent / name


def _weight_spec(path: Path, raw: Any) -> _WeightSpec:
    """One weight spec, its shape and quantisation checked (see :class:`_WeightSpec`)."""
    if not isinstance(raw, dict) or not isinstance(raw.get("name"), str):
        raise ModelFileError(f"{path}: a weight spec has no name")
    name = raw["name"]
    shape = raw.get("shape")
    if not isinstance(shape, list) or len(shape) > 32:
        raise ModelFileError(f"{path}: weight {name!r} has a malformed shape {shape!r}")
    if not all(isinstance(size, int) and not isinstance(size, bool) for size in shape):
        raise ModelFileError(f"{path}: weight {name!r} has a malformed shape {shape!r}")
    if any(size < 0 for size in shape):
        raise ModelFileError(f"{path}: weight {name!r} has a negative dimension {shape}")
    count = math.prod(shape)
    if count > MAX_TENSOR_ELEMENTS:
        raise ModelFileError(
            f"{path}: weight {name!r} has the absurd shape {shape} ({count:,} elements, "
            f"more than {MAX_TENSOR_ELEMENTS:,})"
        )
    dtype = raw.get("dtype")
    if dtype not in _VALUE_BYTES:
        raise ModelFileError(f"{path}: weight {name!r} has the unsupported dtype {dtype!r}")
    stored, scale, offset = _quantisation(path, name, dtype, raw.get("quantization"))
    size = _QUANTISED_BYTES.get(stored) or _VALUE_BYTES[stored]
    return _WeightSpec(name, tuple(shape), dtype, stored, scale, offset, count * size)


def _quantisation(path: Path, name: str, dtype: str, raw: Any) -> tuple[str, float, float]:
    """``(stored dtype, scale, min)`` of a weight's quantisation (its own dtype, 1, 0 if none)."""
    if raw is None:
        return dtype, 1.0, 0.0
    stored = raw.get("dtype") if isinstance(raw, dict) else None
    if stored == "float16":
        if dtype != "float32":
            raise ModelFileError(f"{path}: weight {name!r}: float16 quantisation of {dtype}")
        return stored, 1.0, 0.0
    if stored not in ("uint8", "uint16") or dtype == "bool":
        raise ModelFileError(f"{path}: weight {name!r} has an unsupported quantisation {raw!r}")
    scale, offset = raw.get("scale"), raw.get("min")
    numbers = (scale, offset)
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in numbers):
        raise ModelFileError(f"{path}: weight {name!r}: quantisation without a scale and min")
    if not all(math.isfinite(value) for value in numbers):
        raise ModelFileError(
            f"{path}: weight {name!r}: non-finite quantisation scale {scale} or min {offset}"
        )
    return stored, float(scale), float(offset)


def _read_shards(path: Path, shard_paths: list[Path], expected: int) -> bytes:
    """The shards' bytes concatenated; their sizes must add up to ``expected`` exactly
    (checked on the file system before reading)."""
    sizes = []
    for shard in shard_paths:
        if not shard.is_file():
            raise ModelFileError(f"{path}: the weight shard {shard.name} is missing")
        sizes.append(shard.stat().st_size)
    if sum(sizes) != expected:
        raise ModelFileError(
            f"{path}: the weight shards hold {sum(sizes):,} bytes but the weight specs declare "
            f"{expected:,} (truncated or mismatched shards, or wrong shapes)"
        )
    chunks = []
    for shard, size in zip(shard_paths, sizes, strict=True):
        with shard.open("rb") as file:
            chunk = file.read(size + 1)
        if len(chunk) != size:
            raise ModelFileError(f"{path}: the shard {shard.name} changed while being read")
        chunks.append(chunk)
    return b"".join(chunks)


def _decode(path: Path, spec: _WeightSpec, data: bytes) -> np.ndarray:
    """One weight's array (float32, int32 or bool) of its declared shape, dequantised as
    TF.js does (affine in float64, then rounded to float32, or to int32 half up); no NaN
    (infinities are legitimate: nanodet pads with -inf before a max-pool)."""
    if spec.stored == "float16":
        values = np.frombuffer(data, dtype="<f2").astype(np.float32)
    elif spec.stored in ("uint8", "uint16"):
        quantised = np.frombuffer(data, dtype=np.uint8 if spec.stored == "uint8" else "<u2")
        real = quantised.astype(np.float64) * spec.scale + spec.offset
        if spec.dtype == "int32":
            real = np.floor(real + 0.5)
            if np.abs(real).max(initial=0.0) >= 2**31:
                raise ModelFileError(f"{path}: weight {spec.name!r}: values overflow int32")
        values = real.astype(np.float32 if spec.dtype == "float32" else np.int32)
    elif spec.dtype == "bool":
        values = np.frombuffer(data, dtype=np.uint8) != 0
    else:
        values = np.frombuffer(data, dtype="<f4" if spec.dtype == "float32" else "<i4")
        values = values.astype(np.float32 if spec.dtype == "float32" else np.int32)
    if values.dtype == np.float32 and np.isnan(values).any():
        raise ModelFileError(f"{path}: weight {spec.name!r} holds NaN values")
    return values.reshape(spec.shape)

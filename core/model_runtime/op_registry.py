"""How an op of the graph becomes a torch function: the registry and the helpers op modules
share.

Each TensorFlow op type has a *builder* (registered with :func:`register`) that reads a node's
attributes and its constant inputs once, at load time, and returns a :class:`PreparedOp`: the
function that runs the node on torch tensors, the tensors it prepared (e.g. a convolution's
kernel in torch's layout) and which constant inputs it absorbed (those are not passed again).
Malformed attributes raise :class:`NodeError`; the graph model adds the file and node name.

Conventions: tensors follow TensorFlow's layouts (images NHWC); integer tensors are int32 (as
in TF.js, which stores int64 constants as int32), booleans ``torch.bool``, floats the model's
float dtype (float32 unless the model was moved to another with ``GraphModel.to``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import torch

from hkpd.model_runtime.graph_file import MAX_TENSOR_ELEMENTS, GraphNode

OpFunction = Callable[
    [list[torch.Tensor | None], dict[str, torch.Tensor]], tuple[torch.Tensor, ...]
]
"""``function(inputs, params) -> outputs``: ``inputs`` in the node's order (None where the
builder absorbed a constant), ``params`` the op's prepared tensors (moved with the model)."""


class NodeError(ValueError):
    """A node's attributes or inputs are malformed or unsupported (message without the node's
    name: the graph model adds it and the file's)."""


@dataclass
class PreparedOp:
    """One node, ready to run: see :data:`OpFunction`."""

    function: OpFunction
    params: dict[str, torch.Tensor] = field(default_factory=dict)
    absorbed: frozenset[int] = frozenset()


Builder = Callable[[GraphNode, list[torch.Tensor | None]], PreparedOp]
"""``builder(node, constants)``: ``constants[i]`` is input i's value if it is a constant of the
graph (after folding), else None."""

OP_BUILDERS: dict[str, Builder] = {}
"""Every implemented op type -> its builder."""

FLOAT_MARKER = "float_dtype"
"""Name of the empty param whose dtype says the model's float dtype (ops that make floats,
like ``Cast``, read it; ``GraphModel.to(dtype=...)`` converts it with the other params)."""


def register(*op_types: str) -> Callable[[Builder], Builder]:
    """Decorator: ``builder`` implements ``op_types``."""

    def decorate(builder: Builder) -> Builder:
        for op_type in op_types:
            OP_BUILDERS[op_type] = builder
        return builder

    return decorate


def simple(function: Callable[..., torch.Tensor]) -> PreparedOp:
    """A node whose one output is ``function(*inputs)``."""
    return PreparedOp(lambda inputs, params: (function(*inputs),))


def expect_inputs(node: GraphNode, count: int | Sequence[int]) -> None:
    """Raises NodeError unless the node has ``count`` inputs (or one of the counts)."""
    allowed = (count,) if isinstance(count, int) else tuple(count)
    if len(node.inputs) not in allowed:
        raise NodeError(f"{len(node.inputs)} inputs, expected {' or '.join(map(str, allowed))}")


def attribute(node: GraphNode, key: str, kind: type | tuple[type, ...], default: Any = None) -> Any:
    """``node.attributes[key]`` checked to be of ``kind`` (``default`` if absent and given)."""
    value = node.attributes.get(key)
    if value is None:
        if default is None:
            raise NodeError(f"the attribute {key!r} is missing")
        return default
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if isinstance(value, bool) and bool not in kinds:
        raise NodeError(f"the attribute {key!r} is {value!r}, not a {kinds[0].__name__}")
    if not isinstance(value, kinds):
        raise NodeError(f"the attribute {key!r} is {value!r}, not a {kinds[0].__name__}")
    return value


def int_list(node: GraphNode, key: str, length: int, default: list[int] | None = None) -> list[int]:
    """An int-list attribute of exactly ``length`` items (``default`` if absent or empty)."""
    value = node.attributes.get(key)
    if (value is None or value == []) and default is not None:
        return list(default)
    if not isinstance(value, list) or len(value) != length:
        raise NodeError(f"the attribute {key!r} is {value!r}, not a list of {length} integers")
    if not all(isinstance(item, int) and not isinstance(item, bool) for item in value):
        raise NodeError(f"the attribute {key!r} is {value!r}, not a list of integers")
    return value


def constant_ints(constants: list[torch.Tensor | None], index: int) -> list[int] | None:
    """Input ``index``'s values (flattened) as a list of ints if it is an integer constant,
    else None."""
    value = constants[index] if index < len(constants) else None
    if value is None:
        return None
    if value.is_floating_point() or value.numel() > 64:
        raise NodeError(
            f"input {index} must hold a few integers, got {value.dtype} {list(value.shape)}"
        )
    return [int(item) for item in value.reshape(-1).tolist()]


def ints_now(fixed: list[int] | None, inputs: list[torch.Tensor | None], index: int) -> list[int]:
    """``fixed`` (an absorbed constant's ints) or input ``index``'s values, read now."""
    if fixed is not None:
        return fixed
    value = inputs[index]
    assert value is not None
    if value.is_floating_point() or value.numel() > 64:
        raise NodeError(
            f"input {index} must hold a few integers, got {value.dtype} {list(value.shape)}"
        )
    return [int(item) for item in value.reshape(-1).tolist()]


def absorbed_where(*pairs: tuple[int, object]) -> frozenset[int]:
    """The input indices whose prepared value (second item) is not None."""
    return frozenset(index for index, value in pairs if value is not None)


def check_size(shape: Sequence[int], what: str) -> None:
    """Raises NodeError if ``shape`` has a negative size or more than MAX_TENSOR_ELEMENTS
    elements (before anything of that shape is allocated)."""
    if any(size < 0 for size in shape):
        raise NodeError(f"{what} has a negative size: {list(shape)}")
    if math.prod(shape) > MAX_TENSOR_ELEMENTS:
        raise NodeError(
            f"{what} would have {math.prod(shape):,} elements (shape {list(shape)}), more than "
            f"{MAX_TENSOR_ELEMENTS:,}"
        )


def normalised_axis(axis: int, rank: int) -> int:
    """``axis`` in ``[-rank, rank)`` as a non-negative index; NodeError if out of range."""
    if not -rank <= axis < rank:
        raise NodeError(f"axis {axis} is out of range for a tensor of rank {rank}")
    return axis % rank


TF_DTYPES_INT = frozenset({"DT_INT32", "DT_INT64", "DT_INT16", "DT_INT8", "DT_UINT8"})
"""TensorFlow dtypes that run as int32 here (as in TF.js)."""


def torch_dtype(tf_dtype: str, float_dtype: torch.dtype) -> torch.dtype:
    """The torch dtype a TensorFlow dtype name runs as (floats as ``float_dtype``)."""
    if tf_dtype in ("DT_FLOAT", "DT_HALF", "DT_DOUBLE", "DT_BFLOAT16"):
        return float_dtype
    if tf_dtype in TF_DTYPES_INT:
        return torch.int32
    if tf_dtype == "DT_BOOL":
        return torch.bool
    raise NodeError(f"the dtype {tf_dtype} is not supported")

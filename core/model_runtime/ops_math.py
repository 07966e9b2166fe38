"""Element-wise ops, reductions, softmax and casts with TensorFlow's (and TF.js's) semantics:
numpy broadcasting, integer division rounding down, ``FloorMod`` taking the divisor's sign,
``Mean`` dividing each element before summing (as TF.js's CPU backend does)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
import torch.nn.functional as functional

from hkpd.model_runtime.graph_file import GraphNode
from hkpd.model_runtime.op_registry import (
    FLOAT_MARKER,
    NodeError,
    PreparedOp,
    absorbed_where,
    attribute,
    check_size,
    constant_ints,
    expect_inputs,
    ints_now,
    normalised_axis,
    register,
    simple,
    torch_dtype,
)


def _floor_divide(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    if a.is_floating_point():
        return torch.floor(a / b)
    return torch.div(a, b, rounding_mode="floor")


def _real_divide(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    if a.is_floating_point():
        return a / b
    return torch.div(a, b, rounding_mode="trunc")


_BINARY = {
    "Add": torch.add,
    "AddV2": torch.add,
    "Sub": torch.sub,
    "Mul": torch.mul,
    "RealDiv": _real_divide,
    "Div": _real_divide,
    "FloorDiv": _floor_divide,
    "FloorMod": torch.remainder,
    "Minimum": torch.minimum,
    "Maximum": torch.maximum,
    "SquaredDifference": lambda a, b: (a - b) * (a - b),
    "Pow": torch.pow,
    "Equal": torch.eq,
    "NotEqual": torch.ne,
    "Greater": torch.gt,
    "GreaterEqual": torch.ge,
    "Less": torch.lt,
    "LessEqual": torch.le,
    "LogicalAnd": torch.logical_and,
    "LogicalOr": torch.logical_or,
}
"""Binary ops: ``output = function(a, b)`` with broadcasting."""


def broadcast_shape(first: Sequence[int], second: Sequence[int]) -> list[int]:
    """numpy's broadcast of two shapes; NodeError if they do not broadcast."""
    rank = max(len(first), len(second))
    padded_first = [1] * (rank - len(first)) + list(first)
    padded_second = [1] * (rank - len(second)) + list(second)
    shape = []
    for a, b in zip(padded_first, padded_second, strict=True):
        if a != b and 1 not in (a, b):
            raise NodeError(f"the shapes {list(first)} and {list(second)} do not broadcast")
        shape.append(b if a == 1 else a)
    return shape


@register(*_BINARY)
def _binary(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(a, b) -> a ∘ b``, broadcast; the broadcast shape is checked against the size cap."""
    expect_inputs(node, 2)
    function = _BINARY[node.op]

    def run(inputs, params):
        a, b = inputs
        if a.dtype != b.dtype:
            raise NodeError(f"{node.op} of {a.dtype} and {b.dtype}")
        check_size(broadcast_shape(a.shape, b.shape), "the result")
        return (function(a, b),)

    return PreparedOp(run)


_UNARY = {
    "Identity": lambda x: x,
    "Relu": torch.relu,
    "Relu6": lambda x: torch.clamp(x, 0.0, 6.0),
    "Elu": functional.elu,
    "Sigmoid": torch.sigmoid,
    "Tanh": torch.tanh,
    "Sqrt": torch.sqrt,
    "Rsqrt": torch.rsqrt,
    "Square": lambda x: x * x,
    "Exp": torch.exp,
    "Log": torch.log,
    "Neg": torch.neg,
    "Abs": torch.abs,
    "Floor": torch.floor,
    "Ceil": torch.ceil,
    "LogicalNot": torch.logical_not,
    "Reciprocal": torch.reciprocal,
    "Sin": torch.sin,
    "Cos": torch.cos,
    "ZerosLike": torch.zeros_like,
}
"""Unary ops: ``output = function(x)``."""


@register(*_UNARY)
def _unary(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> f(x)``, same shape."""
    expect_inputs(node, 1)
    return simple(_UNARY[node.op])


@register("LeakyRelu")
def _leaky_relu(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> x if x ≥ 0 else alpha·x`` (attribute ``alpha``, TF's default 0.2)."""
    expect_inputs(node, 1)
    alpha = attribute(node, "alpha", (float, int), 0.2)
    return simple(lambda x: functional.leaky_relu(x, float(alpha)))


@register("Prelu")
def _prelu(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, alpha) -> x if x ≥ 0 else alpha·x`` (alpha broadcast)."""
    expect_inputs(node, 2)
    return simple(lambda x, alpha: torch.where(x < 0, x * alpha, x))


@register("Softmax")
def _softmax(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``logits (..., K) -> softmax over the last axis``."""
    expect_inputs(node, 1)
    return simple(lambda x: torch.softmax(x, dim=-1))


def _reduction_axes(axes: list[int], rank: int) -> list[int]:
    return sorted({normalised_axis(axis, rank) for axis in axes})


def _mean(x: torch.Tensor, axes: list[int], keep: bool) -> torch.Tensor:
    """TF.js's mean: each element divided by the count, then summed (float32 inputs summed in
    float64 and rounded once, as TF.js's JavaScript sum does)."""
    if not axes:
        return x
    count = 1
    for axis in axes:
        count *= x.shape[axis]
    scaled = x / torch.tensor(float(count), dtype=x.dtype, device=x.device)
    if x.dtype == torch.float32:
        return scaled.double().sum(dim=axes, keepdim=keep).float()
    return scaled.sum(dim=axes, keepdim=keep)


_REDUCTIONS = {
    "Mean": _mean,
    "Sum": lambda x, axes, keep: x.sum(dim=axes, keepdim=keep) if axes else x,
    "Max": lambda x, axes, keep: x.amax(dim=axes, keepdim=keep) if axes else x,
    "Min": lambda x, axes, keep: x.amin(dim=axes, keepdim=keep) if axes else x,
}


@register(*_REDUCTIONS)
def _reduction(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, axes) -> x reduced over axes`` (``keep_dims`` keeps them as size 1)."""
    expect_inputs(node, 2)
    keep = attribute(node, "keep_dims", bool, False)
    axes_fixed = constant_ints(constants, 1)
    function = _REDUCTIONS[node.op]

    def run(inputs, params):
        x = inputs[0]
        axes = _reduction_axes(ints_now(axes_fixed, inputs, 1), x.dim())
        return (function(x, axes, keep),)

    return PreparedOp(run, absorbed=absorbed_where((1, axes_fixed)))


@register("Cast")
def _cast(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> x as DstT`` (floats to ints truncate toward zero, to bool: x ≠ 0)."""
    expect_inputs(node, 1)
    target = attribute(node, "DstT", str)
    torch_dtype(target, torch.float32)  # refuse unsupported dtypes at load

    def run(inputs, params):
        return (inputs[0].to(torch_dtype(target, params[FLOAT_MARKER].dtype)),)

    return PreparedOp(run, params={FLOAT_MARKER: torch.empty(0)})


@register("ArgMax", "ArgMin")
def _arg_extreme(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, axis) -> int32 index of the first largest (smallest) value along axis``."""
    expect_inputs(node, 2)
    axis_fixed = constant_ints(constants, 1)
    function = torch.argmax if node.op == "ArgMax" else torch.argmin

    def run(inputs, params):
        (axis,) = ints_now(axis_fixed, inputs, 1)
        x = inputs[0]
        return (function(x, dim=normalised_axis(axis, x.dim())).to(torch.int32),)

    return PreparedOp(run, absorbed=absorbed_where((1, axis_fixed)))


@register("Fill")
def _fill(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(shape, value) -> a tensor of that shape filled with the scalar value``."""
    expect_inputs(node, 2)
    shape_fixed = constant_ints(constants, 0)

    def run(inputs, params):
        shape = ints_now(shape_fixed, inputs, 0)
        check_size(shape, "the filled tensor")
        value = inputs[1]
        return (value.reshape(()).expand(shape).clone(),)

    return PreparedOp(run, absorbed=absorbed_where((0, shape_fixed)))


@register("AddN")
def _add_n(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x_1 … x_N) -> x_1 + … + x_N`` (same shapes), added in order as TF.js does."""
    if not node.inputs:
        raise NodeError("AddN needs at least one input")

    def run(inputs, params):
        total = inputs[0]
        for term in inputs[1:]:
            if term.shape != total.shape:
                raise NodeError(f"AddN of shapes {list(total.shape)} and {list(term.shape)}")
            total = total + term
        return (total,)

    return PreparedOp(run)


@register("BiasAdd")
def _bias_add(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x (..., C), bias (C,)) -> x + bias`` (NHWC only)."""
    expect_inputs(node, 2)
    layout = attribute(node, "data_format", str, "NHWC")
    if layout != "NHWC":
        raise NodeError(f"BiasAdd with data format {layout!r} is not supported (only NHWC)")

    def run(inputs, params):
        x, bias = inputs
        if bias.dim() != 1 or x.dim() < 1 or x.shape[-1] != bias.shape[0]:
            raise NodeError(f"BiasAdd of {list(bias.shape)} to {list(x.shape)}")
        return (x + bias,)

    return PreparedOp(run)


@register("Select", "SelectV2")
def _select(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(condition, a, b) -> a where condition else b``: SelectV2 broadcasts; Select's
    condition is x's shape or a vector over its first axis."""
    expect_inputs(node, 3)

    def run(inputs, params):
        condition, a, b = inputs
        if node.op == "Select" and condition.dim() == 1 and a.dim() > 1:
            condition = condition.reshape(-1, *([1] * (a.dim() - 1)))
        check_size(broadcast_shape(broadcast_shape(condition.shape, a.shape), b.shape), "Select")
        return (torch.where(condition.bool(), a, b),)

    return PreparedOp(run)


@register("Range")
def _range(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(start, limit, delta) -> start + i·delta`` for i while before limit (ints or floats)."""
    expect_inputs(node, 3)

    def run(inputs, params):
        start, limit, delta = (value.reshape(()) for value in inputs)
        step = delta.item()
        if step == 0:
            raise NodeError("Range with a zero delta")
        count = max(0, math.ceil((limit.item() - start.item()) / step))
        check_size([count], "the range")
        steps = torch.arange(count, device=start.device).to(start.dtype)
        return (start + steps * delta,)

    return PreparedOp(run)


@register("Size")
def _size(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> its number of elements`` (int32 scalar)."""
    expect_inputs(node, 1)

    def run(inputs, params):
        return (torch.tensor(inputs[0].numel(), dtype=torch.int32, device=inputs[0].device),)

    return PreparedOp(run)

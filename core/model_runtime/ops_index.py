"""Ops that pick elements by index: gathers, scatters into a dense tensor and top-k, with
TensorFlow's semantics (out-of-range indices are errors, never wrapped or clamped; ``TopKV2``
orders ties by index as TF.js does)."""

from __future__ import annotations

import torch

from hkpd.model_runtime.graph_file import GraphNode
from hkpd.model_runtime.op_registry import (
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
)


def _checked_indices(indices: torch.Tensor, size: int, what: str) -> torch.Tensor:
    """``indices`` as int64, NodeError if any lies outside ``[0, size)``."""
    if indices.is_floating_point():
        raise NodeError(f"{what} indices must be integers, got {indices.dtype}")
    indices = indices.long()
    if indices.numel() and (int(indices.min()) < 0 or int(indices.max()) >= size):
        raise NodeError(f"{what} index out of range [0, {size})")
    return indices


@register("GatherV2")
def _gather(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(params, indices, axis) -> params' slices at indices along axis``: shape
    ``params.shape[:axis] + indices.shape + params.shape[axis+1:]`` (``batch_dims`` 0)."""
    expect_inputs(node, 3)
    if attribute(node, "batch_dims", int, 0) != 0:
        raise NodeError("GatherV2 with batch_dims other than 0 is not supported")
    axis_fixed = constant_ints(constants, 2)

    def run(inputs, params):
        source, indices = inputs[0], inputs[1]
        (axis,) = ints_now(axis_fixed, inputs, 2)
        dim = normalised_axis(axis, source.dim())
        shape = [*source.shape[:dim], *indices.shape, *source.shape[dim + 1 :]]
        check_size(shape, "the gathered tensor")
        flat = _checked_indices(indices, source.shape[dim], "GatherV2").reshape(-1)
        picked = source.index_select(dim, flat)
        return (picked.reshape(shape),)

    return PreparedOp(run, absorbed=absorbed_where((2, axis_fixed)))


@register("GatherNd")
def _gather_nd(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(params, indices (..., K)) -> params[indices[..., 0], …, indices[..., K-1]]``: shape
    ``indices.shape[:-1] + params.shape[K:]``."""
    expect_inputs(node, 2)

    def run(inputs, params):
        source, indices = inputs
        depth = indices.shape[-1] if indices.dim() else 0
        if indices.dim() == 0 or depth > source.dim():
            raise NodeError(f"GatherNd indices {list(indices.shape)} for {list(source.shape)}")
        check_size([*indices.shape[:-1], *source.shape[depth:]], "the gathered tensor")
        linear = torch.zeros(indices.shape[:-1], dtype=torch.long, device=source.device)
        for level in range(depth):
            size = source.shape[level]
            level_indices = _checked_indices(indices[..., level], size, "GatherNd")
            linear = linear * size + level_indices
        rows = source.reshape(-1, *source.shape[depth:])
        picked = rows.index_select(0, linear.reshape(-1))
        return (picked.reshape(*indices.shape[:-1], *source.shape[depth:]),)

    return PreparedOp(run)


@register("SparseToDense")
def _sparse_to_dense(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(indices (N, R) or (N,) or scalar, shape (R,), values (N,) or scalar, default) ->``
    a dense tensor of ``shape`` holding ``default`` except ``values`` at ``indices``."""
    expect_inputs(node, 4)
    shape_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        indices, _, values, default = inputs
        shape = ints_now(shape_fixed, inputs, 1)
        check_size(shape, "the dense tensor")
        dense = default.reshape(()).expand(shape).clone()
        rows = indices.reshape(-1, 1) if indices.dim() < 2 else indices
        if rows.numel() == 0:
            return (dense,)
        if rows.shape[1] != len(shape):
            raise NodeError(f"SparseToDense indices {list(indices.shape)} for shape {shape}")
        linear = torch.zeros(rows.shape[0], dtype=torch.long, device=dense.device)
        for level, size in enumerate(shape):
            linear = linear * size + _checked_indices(rows[:, level], size, "SparseToDense")
        flat = dense.reshape(-1)
        flat[linear] = values.reshape(-1).expand(rows.shape[0]).to(dense.dtype)
        return (flat.reshape(shape),)

    return PreparedOp(run, absorbed=absorbed_where((1, shape_fixed)))


@register("TopKV2")
def _top_k(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x (..., N), k) -> (values (..., k), int32 indices (..., k))``: the k largest along
    the last axis, largest first, equal values in order of index (as TF.js's sort)."""
    expect_inputs(node, 2)
    k_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        (k,) = ints_now(k_fixed, inputs, 1)
        if x.dim() == 0 or not 0 <= k <= x.shape[-1]:
            raise NodeError(f"TopKV2 k={k} for a last axis of {list(x.shape)[-1:]}")
        values, indices = torch.sort(x, dim=-1, descending=True, stable=True)
        return values[..., :k], indices[..., :k].to(torch.int32)

    return PreparedOp(run, absorbed=absorbed_where((1, k_fixed)))


@register("Shape")
def _shape(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> its shape as an int32 vector``."""
    expect_inputs(node, 1)

    def run(inputs, params):
        x = inputs[0]
        return (torch.tensor(list(x.shape), dtype=torch.int32, device=x.device),)

    return PreparedOp(run)

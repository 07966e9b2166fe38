"""Ops that move elements without arithmetic: reshape, transpose, expand/squeeze, concatenate,
stack/unstack, split, pad and strided slices, with TensorFlow's semantics (negative axes count
from the end; ``StridedSlice``'s five masks; ``SplitV`` may infer one size with -1)."""

from __future__ import annotations

import math

import torch
import torch.nn.functional as functional

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


def _reshaped(x: torch.Tensor, shape: list[int]) -> torch.Tensor:
    """``x`` reshaped to ``shape`` (one -1 inferred), NodeError if the counts differ."""
    if shape.count(-1) > 1 or any(size < -1 for size in shape):
        raise NodeError(f"cannot reshape to {shape}")
    known = math.prod(size for size in shape if size != -1)
    if -1 in shape:
        if known == 0 or x.numel() % known:
            raise NodeError(f"cannot reshape {list(x.shape)} to {shape}")
    elif known != x.numel():
        raise NodeError(f"cannot reshape {list(x.shape)} ({x.numel()} elements) to {shape}")
    return x.reshape(shape)


@register("Reshape")
def _reshape(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, shape) -> x with that shape``."""
    expect_inputs(node, 2)
    shape_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        return (_reshaped(inputs[0], ints_now(shape_fixed, inputs, 1)),)

    return PreparedOp(run, absorbed=absorbed_where((1, shape_fixed)))


@register("Transpose")
def _transpose(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, perm) -> x with axes permuted`` (a view; later ops copy when they must)."""
    expect_inputs(node, 2)
    perm_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        perm = ints_now(perm_fixed, inputs, 1)
        if sorted(normalised_axis(axis, x.dim()) for axis in perm) != list(range(x.dim())):
            raise NodeError(f"{perm} is not a permutation of {x.dim()} axes")
        return (x.permute(perm),)

    return PreparedOp(run, absorbed=absorbed_where((1, perm_fixed)))


@register("ExpandDims")
def _expand_dims(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, axis) -> x with a new axis of size 1 at axis (in [-rank-1, rank])``."""
    expect_inputs(node, 2)
    axis_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        (axis,) = ints_now(axis_fixed, inputs, 1)
        return (x.unsqueeze(normalised_axis(axis, x.dim() + 1)),)

    return PreparedOp(run, absorbed=absorbed_where((1, axis_fixed)))


@register("Squeeze")
def _squeeze(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> x without the size-1 axes squeeze_dims`` (all size-1 axes if none are named)."""
    expect_inputs(node, 1)
    axes = node.attributes.get("squeeze_dims") or []

    def run(inputs, params):
        x = inputs[0]
        chosen = [normalised_axis(axis, x.dim()) for axis in axes]
        if any(x.shape[axis] != 1 for axis in chosen):
            raise NodeError(f"cannot squeeze axes {axes} of shape {list(x.shape)}")
        if not chosen:
            chosen = [axis for axis, size in enumerate(x.shape) if size == 1]
        keep = [size for axis, size in enumerate(x.shape) if axis not in chosen]
        return (x.reshape(keep),)

    return PreparedOp(run)


@register("ConcatV2")
def _concat(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x_1 … x_N, axis) -> the x_i concatenated along axis``."""
    if len(node.inputs) < 2:
        raise NodeError("ConcatV2 needs at least one tensor and an axis")
    last = len(node.inputs) - 1
    axis_fixed = constant_ints(constants, last)

    def run(inputs, params):
        (axis,) = ints_now(axis_fixed, inputs, last)
        tensors = inputs[:last]
        check_size([sum(t.numel() for t in tensors)], "the concatenation")
        return (torch.cat(tensors, dim=normalised_axis(axis, tensors[0].dim())),)

    return PreparedOp(run, absorbed=absorbed_where((last, axis_fixed)))


@register("Pack")
def _pack(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x_1 … x_N) -> stacked along a new axis`` (attribute ``axis``)."""
    axis = attribute(node, "axis", int, 0)

    def run(inputs, params):
        check_size([sum(t.numel() for t in inputs)], "the stack")
        return (torch.stack(inputs, dim=normalised_axis(axis, inputs[0].dim() + 1)),)

    return PreparedOp(run)


@register("Unpack")
def _unpack(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x -> num tensors, x's slices along axis`` (attributes ``axis``, ``num``)."""
    expect_inputs(node, 1)
    axis = attribute(node, "axis", int, 0)
    count = attribute(node, "num", int)

    def run(inputs, params):
        x = inputs[0]
        dim = normalised_axis(axis, x.dim())
        if x.shape[dim] != count:
            raise NodeError(f"cannot unpack {count} from axis {axis} of {list(x.shape)}")
        return tuple(x.unbind(dim))

    return PreparedOp(run)


@register("SplitV")
def _split_v(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, sizes, axis) -> len(sizes) pieces along axis`` (one size may be -1: the rest)."""
    expect_inputs(node, 3)
    sizes_fixed = constant_ints(constants, 1)
    axis_fixed = constant_ints(constants, 2)

    def run(inputs, params):
        x = inputs[0]
        sizes = list(ints_now(sizes_fixed, inputs, 1))
        (axis,) = ints_now(axis_fixed, inputs, 2)
        dim = normalised_axis(axis, x.dim())
        if sizes.count(-1) == 1:
            sizes[sizes.index(-1)] = x.shape[dim] - (sum(sizes) + 1)
        if any(size < 0 for size in sizes) or sum(sizes) != x.shape[dim]:
            raise NodeError(f"cannot split axis {axis} of {list(x.shape)} into {sizes}")
        return tuple(torch.split(x, sizes, dim=dim))

    return PreparedOp(run, absorbed=absorbed_where((1, sizes_fixed), (2, axis_fixed)))


@register("Split")
def _split(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(axis, x) -> num_split equal pieces along axis``."""
    expect_inputs(node, 2)
    count = attribute(node, "num_split", int)
    axis_fixed = constant_ints(constants, 0)

    def run(inputs, params):
        x = inputs[1]
        (axis,) = ints_now(axis_fixed, inputs, 0)
        dim = normalised_axis(axis, x.dim())
        if count <= 0 or x.shape[dim] % count:
            raise NodeError(f"cannot split axis {axis} of {list(x.shape)} into {count}")
        return tuple(torch.split(x, x.shape[dim] // count, dim=dim))

    return PreparedOp(run, absorbed=absorbed_where((0, axis_fixed)))


@register("Pad", "PadV2")
def _pad(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, paddings (rank, 2)[, value]) -> x padded with zeros (or the scalar value)``."""
    expect_inputs(node, 2 if node.op == "Pad" else 3)
    pads_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        pads = ints_now(pads_fixed, inputs, 1)
        if len(pads) != 2 * x.dim() or any(pad < 0 for pad in pads):
            raise NodeError(f"paddings {pads} do not fit a tensor of rank {x.dim()}")
        padded = [size + pads[2 * axis] + pads[2 * axis + 1] for axis, size in enumerate(x.shape)]
        check_size(padded, "the padded tensor")
        value = float(inputs[2].reshape(()).item()) if node.op == "PadV2" else 0.0
        flat = [pad for axis in reversed(range(x.dim())) for pad in pads[2 * axis : 2 * axis + 2]]
        return (functional.pad(x, flat, value=value),)

    return PreparedOp(run, absorbed=absorbed_where((1, pads_fixed)))


@register("StridedSlice")
def _strided_slice(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, begin, end, strides) -> x[begin:end:strides]`` with TF's begin/end/ellipsis/
    new-axis/shrink-axis masks (bit i refers to the i-th entry of begin/end/strides)."""
    expect_inputs(node, 4)
    masks = {
        key: attribute(node, f"{key}_mask", int, 0)
        for key in ("begin", "end", "ellipsis", "new_axis", "shrink_axis")
    }
    fixed = [constant_ints(constants, index) for index in (1, 2, 3)]

    def run(inputs, params):
        begin, end, strides = (ints_now(fixed[i], inputs, i + 1) for i in range(3))
        if not len(begin) == len(end) == len(strides) or 0 in strides:
            raise NodeError(f"malformed slice begin {begin}, end {end}, strides {strides}")
        entries = _dense_slice_entries(inputs[0].dim(), begin, end, strides, masks)
        return (_apply_slice_entries(inputs[0], entries),)

    absorbed = absorbed_where(*((index + 1, value) for index, value in enumerate(fixed)))
    return PreparedOp(run, absorbed=absorbed)


def _bit(mask: int, index: int) -> bool:
    return bool((mask >> index) & 1)


def _dense_slice_entries(
    rank: int, begin: list[int], end: list[int], strides: list[int], masks: dict[str, int]
) -> list[tuple]:
    """The slice spec expanded to one entry per output step: ``("new",)``, ``("shrink", i)``
    or ``("slice", begin|None, end|None, stride)``, covering all ``rank`` input axes."""
    consumed = sum(
        1
        for index in range(len(begin))
        if not _bit(masks["ellipsis"], index) and not _bit(masks["new_axis"], index)
    )
    entries: list[tuple] = []
    seen_ellipsis = False
    for index in range(len(begin)):
        if _bit(masks["ellipsis"], index):
            if seen_ellipsis:
                raise NodeError("more than one ellipsis in a strided slice")
            seen_ellipsis = True
            entries += [("slice", None, None, 1)] * (rank - consumed)
        elif _bit(masks["new_axis"], index):
            entries.append(("new",))
        elif _bit(masks["shrink_axis"], index):
            entries.append(("shrink", begin[index]))
        else:
            start = None if _bit(masks["begin"], index) else begin[index]
            stop = None if _bit(masks["end"], index) else end[index]
            entries.append(("slice", start, stop, strides[index]))
    if not seen_ellipsis:
        if consumed > rank:
            raise NodeError(f"a strided slice of {consumed} axes on a tensor of rank {rank}")
        entries += [("slice", None, None, 1)] * (rank - consumed)
    return entries


def _apply_slice_entries(x: torch.Tensor, entries: list[tuple]) -> torch.Tensor:
    """``x`` sliced by :func:`_dense_slice_entries`' entries (numpy's clamping of bounds)."""
    axis = 0
    for entry in entries:
        if entry[0] == "new":
            x = x.unsqueeze(axis)
            axis += 1
        elif entry[0] == "shrink":
            if axis >= x.dim() or not -x.shape[axis] <= entry[1] < x.shape[axis]:
                raise NodeError(f"index {entry[1]} is out of range in a strided slice")
            x = x.select(axis, entry[1])
        else:
            if axis >= x.dim():
                raise NodeError("a strided slice names more axes than the tensor has")
            start, stop, step = slice(*entry[1:]).indices(x.shape[axis])
            if step > 0:
                x = x[(slice(None),) * axis + (slice(start, stop, step),)]
            else:
                picked = torch.arange(start, stop, step, device=x.device)
                x = x.index_select(axis, picked)
            axis += 1
    return x


@register("Slice")
def _slice(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, begin, size) -> x[begin : begin + size]`` per axis (size -1: to the end)."""
    expect_inputs(node, 3)
    begin_fixed, size_fixed = constant_ints(constants, 1), constant_ints(constants, 2)

    def run(inputs, params):
        x = inputs[0]
        begin, size = ints_now(begin_fixed, inputs, 1), ints_now(size_fixed, inputs, 2)
        if len(begin) != x.dim() or len(size) != x.dim():
            raise NodeError(f"Slice begin {begin}, size {size} for {list(x.shape)}")
        for axis, (start, count) in enumerate(zip(begin, size, strict=True)):
            count = x.shape[axis] - start if count == -1 else count
            if start < 0 or count < 0 or start + count > x.shape[axis]:
                raise NodeError(f"Slice begin {begin}, size {size} for {list(x.shape)}")
            x = x.narrow(axis, start, count)
        return (x,)

    return PreparedOp(run, absorbed=absorbed_where((1, begin_fixed), (2, size_fixed)))


@register("Tile")
def _tile(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x, multiples) -> x repeated multiples[i] times along axis i``."""
    expect_inputs(node, 2)
    multiples_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        multiples = ints_now(multiples_fixed, inputs, 1)
        if len(multiples) != x.dim() or min(multiples, default=1) < 0:
            raise NodeError(f"Tile multiples {multiples} for {list(x.shape)}")
        check_size([s * m for s, m in zip(x.shape, multiples, strict=True)], "the tiled tensor")
        return (x.repeat(multiples),)

    return PreparedOp(run, absorbed=absorbed_where((1, multiples_fixed)))

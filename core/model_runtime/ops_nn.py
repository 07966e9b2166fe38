"""Convolutions, matrix products, pooling and bilinear resizing with TensorFlow's semantics.

Images are NHWC; TF's ``SAME`` padding puts the odd pixel after (bottom/right), which torch
cannot express, so such inputs are padded explicitly first. Constant kernels are converted to
torch's layout once, at load: ``Conv2D`` filters ``(kh, kw, in, out)`` to ``(out, in, kh, kw)``
and depthwise filters ``(kh, kw, C, M)`` to ``(C·M, 1, kh, kw)`` (output channel c·M + m, as
TF orders them). Fused ops (``_FusedConv2D``, ``FusedDepthwiseConv2dNative``,
``_FusedMatMul``) add the bias and apply their activation (Relu, Relu6, Elu, Sigmoid, Tanh,
LeakyRelu, Prelu). ``ResizeBilinear`` follows TF.js's CPU kernel to the last bit (source
positions and interpolation in float64, rounded once).
"""

from __future__ import annotations

from collections.abc import Callable

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
    int_list,
    ints_now,
    register,
)

Activation = Callable[[torch.Tensor, torch.Tensor | None], torch.Tensor]
"""``activation(x, alpha)``: alpha is Prelu's slope tensor (None for the others)."""


def _fused_activation(node: GraphNode) -> tuple[bool, Activation | None, bool]:
    """``(adds a bias, activation or None, takes a Prelu alpha input)`` from ``fused_ops``."""
    fused = node.attributes.get("fused_ops") or []
    if not fused:
        return False, None, False
    if fused[0] != "BiasAdd" or len(fused) > 2:
        raise NodeError(f"the fused ops {fused} are not supported (BiasAdd[, activation])")
    if len(fused) == 1:
        return True, None, False
    alpha = float(attribute(node, "leakyrelu_alpha", (float, int), 0.2))
    activations: dict[str, Activation] = {
        "Relu": lambda x, a: torch.relu(x),
        "Relu6": lambda x, a: torch.clamp(x, 0.0, 6.0),
        "Elu": lambda x, a: functional.elu(x),
        "Sigmoid": lambda x, a: torch.sigmoid(x),
        "Tanh": lambda x, a: torch.tanh(x),
        "LeakyRelu": lambda x, a: functional.leaky_relu(x, alpha),
        "Prelu": lambda x, a: torch.where(x < 0, x * a, x),
    }
    if fused[1] not in activations:
        raise NodeError(f"the fused activation {fused[1]!r} is not supported")
    return True, activations[fused[1]], fused[1] == "Prelu"


def _check_fused_inputs(node: GraphNode, base: int, bias: bool, prelu: bool) -> None:
    """A fused op has ``base`` inputs, plus the bias, plus Prelu's alpha."""
    expect_inputs(node, base + int(bias) + int(prelu))
    if bias and attribute(node, "num_args", int, 1) != 1 + int(prelu):
        raise NodeError(f"num_args {node.attributes.get('num_args')} for {node.attributes}")


def same_padding(size: int, kernel: int, stride: int, dilation: int) -> tuple[int, int]:
    """TF's ``SAME`` padding of one axis: ``(before, after)``, the odd pixel after."""
    effective = (kernel - 1) * dilation + 1
    output = -(-size // stride)
    total = max((output - 1) * stride + effective - size, 0)
    return total // 2, total - total // 2


def _window_padding(node: GraphNode) -> Callable[[int, int, int, int, int], tuple[int, ...]]:
    """``pads(height, width, kh, kw, stride_h, stride_w, dil_h, dil_w)`` -> ``(top, bottom,
    left, right)`` for the node's ``padding`` (SAME, VALID or EXPLICIT)."""
    mode = attribute(node, "padding", str)
    if mode == "EXPLICIT":
        explicit = int_list(node, "explicit_paddings", 8)
        if explicit[:2] != [0, 0] or explicit[6:] != [0, 0] or min(explicit) < 0:
            raise NodeError(f"explicit paddings {explicit} pad the batch or channels")
        return lambda *args: tuple(explicit[2:6])
    if mode == "VALID":
        return lambda *args: (0, 0, 0, 0)
    if mode != "SAME":
        raise NodeError(f"the padding {mode!r} is not supported")

    def pads(height, width, kh, kw, sh, sw, dh, dw):
        return (*same_padding(height, kh, sh, dh), *same_padding(width, kw, sw, dw))

    return pads


def _spatial(node: GraphNode, key: str) -> tuple[int, int]:
    """The (height, width) entries of an NHWC attribute such as ``strides``; batch and
    channel entries must be 1."""
    values = int_list(node, key, 4, default=[1, 1, 1, 1])
    if values[0] != 1 or values[3] != 1 or min(values) < 1:
        raise NodeError(f"{key} {values} are not of the form [1, h, w, 1]")
    return values[1], values[2]


def _check_nhwc(node: GraphNode) -> None:
    layout = attribute(node, "data_format", str, "NHWC")
    if layout != "NHWC":
        raise NodeError(f"the data format {layout!r} is not supported (only NHWC)")


def _convolution_runner(node: GraphNode, depthwise: bool) -> Callable[..., torch.Tensor]:
    """``run(x NHWC, weight torch layout, bias or None, input channels the kernel expects) ->
    y NHWC`` for the node's strides, dilations and padding."""
    _check_nhwc(node)
    strides, dilations = _spatial(node, "strides"), _spatial(node, "dilations")
    pads = _window_padding(node)

    def run(
        x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor | None, expected: int
    ) -> torch.Tensor:
        if x.dim() != 4:
            raise NodeError(f"the convolution's input has shape {list(x.shape)}, not NHWC")
        channels = x.shape[3]
        if channels != expected:
            raise NodeError(f"input of {channels} channels for a kernel of {expected}")
        top, bottom, left, right = pads(x.shape[1], x.shape[2], *weight.shape[2:], *strides,
                                        *dilations)  # fmt: skip
        images = x.permute(0, 3, 1, 2)
        padding: tuple[int, int] = (top, left)
        if top != bottom or left != right:
            images = functional.pad(images, (left, right, top, bottom))
            padding = (0, 0)
        groups = channels if depthwise else 1
        out_size = [
            (size + before + after - (kernel - 1) * dilation - 1) // stride + 1
            for size, before, after, kernel, dilation, stride in zip(
                x.shape[1:3], (top, left), (bottom, right), weight.shape[2:], dilations, strides,
                strict=True,
            )
        ]  # fmt: skip
        check_size([x.shape[0], *out_size, weight.shape[0]], "the convolution's output")
        output = functional.conv2d(images, weight, bias, strides, padding, dilations, groups)
        return output.permute(0, 2, 3, 1)

    return run


def _conv_weight(filters: torch.Tensor, depthwise: bool) -> torch.Tensor:
    """A TF filter in torch's layout (see the module's docstring), channels-last in memory."""
    if filters.dim() != 4 or not filters.is_floating_point():
        raise NodeError(f"a convolution filter of shape {list(filters.shape)}")
    if depthwise:
        height, width, channels, multiplier = filters.shape
        weight = filters.permute(2, 3, 0, 1).reshape(channels * multiplier, 1, height, width)
    else:
        weight = filters.permute(3, 2, 0, 1)
    return weight.contiguous(memory_format=torch.channels_last)


@register("Conv2D", "_FusedConv2D", "DepthwiseConv2dNative", "FusedDepthwiseConv2dNative")
def _convolution(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(x (N,H,W,C), filter[, bias (out,)][, alpha]) -> (N,H',W',out)``."""
    depthwise = "Depthwise" in node.op
    bias_fused, activation, prelu = _fused_activation(node)
    _check_fused_inputs(node, 2, bias_fused, prelu)
    convolve = _convolution_runner(node, depthwise)
    params = {}
    fixed_channels = None
    if constants[1] is not None:
        params["weight"] = _conv_weight(constants[1], depthwise)
        fixed_channels = int(constants[1].shape[2])
    if bias_fused and constants[2] is not None:
        params["bias"] = constants[2].reshape(-1)

    def run(inputs, params):
        weight, channels = params.get("weight"), fixed_channels
        if weight is None:
            weight, channels = _conv_weight(inputs[1], depthwise), int(inputs[1].shape[2])
        bias = params.get("bias", inputs[2] if bias_fused else None)
        if bias is not None:
            bias = bias.reshape(-1)
            if bias.numel() != weight.shape[0]:
                raise NodeError(f"a bias of {bias.numel()} for {weight.shape[0]} channels")
        output = convolve(inputs[0], weight, bias, channels)
        if activation is not None:
            output = activation(output, inputs[3] if prelu else None)
        return (output,)

    absorbed = absorbed_where((1, params.get("weight")), (2, params.get("bias")))
    return PreparedOp(run, params=params, absorbed=absorbed)


@register("MatMul", "_FusedMatMul")
def _matmul(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(a (M,K), b (K,N)[, bias (N,)][, alpha]) -> (M,N)`` (``transpose_a``/``_b``)."""
    bias_fused, activation, prelu = _fused_activation(node)
    _check_fused_inputs(node, 2, bias_fused, prelu)
    transpose_a = attribute(node, "transpose_a", bool, False)
    transpose_b = attribute(node, "transpose_b", bool, False)

    def run(inputs, params):
        a, b = inputs[0], inputs[1]
        if a.dim() != 2 or b.dim() != 2:
            raise NodeError(f"MatMul of shapes {list(a.shape)} and {list(b.shape)}")
        a = a.T if transpose_a else a
        b = b.T if transpose_b else b
        if a.shape[1] != b.shape[0]:
            raise NodeError(f"MatMul of shapes {list(a.shape)} and {list(b.shape)}")
        check_size([a.shape[0], b.shape[1]], "the product")
        output = a @ b
        if bias_fused:
            output = output + inputs[2]
        if activation is not None:
            output = activation(output, inputs[3] if prelu else None)
        return (output,)

    return PreparedOp(run)


@register("MaxPool")
def _max_pool(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x (N,H,W,C) -> the maximum over each window`` (padding never wins)."""
    expect_inputs(node, 1)
    _check_nhwc(node)
    window, strides = _spatial(node, "ksize"), _spatial(node, "strides")
    pads = _window_padding(node)

    def run(inputs, params):
        x = inputs[0]
        if x.dim() != 4:
            raise NodeError(f"MaxPool of shape {list(x.shape)}, not NHWC")
        top, bottom, left, right = pads(x.shape[1], x.shape[2], *window, *strides, 1, 1)
        images = x.permute(0, 3, 1, 2)
        if top or bottom or left or right:
            images = functional.pad(images, (left, right, top, bottom), value=-torch.inf)
        output = functional.max_pool2d(images, window, strides)
        return (output.permute(0, 2, 3, 1),)

    return PreparedOp(run)


def _source_rows(out_size: int, in_size: int, align: bool, half: bool, device) -> tuple:
    """TF.js's bilinear source positions along one axis: ``(lower index, upper index,
    fraction)``, (out_size,) each, the fraction in float64."""
    ratio = (in_size - 1) / (out_size - 1) if align and out_size > 1 else in_size / out_size
    positions = torch.arange(out_size, dtype=torch.float64, device=device)
    source = ratio * (positions + 0.5) - 0.5 if half else ratio * positions
    lower = torch.clamp(torch.floor(source), min=0.0)
    upper = torch.clamp(torch.ceil(source), max=float(in_size - 1))
    return lower.long(), upper.long(), source - lower


@register("ResizeBilinear")
def _resize_bilinear(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``(images (N,H,W,C), size (2,)) -> (N, size[0], size[1], C)`` bilinear
    (``align_corners``, ``half_pixel_centers`` as TF)."""
    expect_inputs(node, 2)
    align = attribute(node, "align_corners", bool, False)
    half = attribute(node, "half_pixel_centers", bool, False)
    if align and half:
        raise NodeError("align_corners and half_pixel_centers cannot both be set")
    size_fixed = constant_ints(constants, 1)

    def run(inputs, params):
        x = inputs[0]
        size = ints_now(size_fixed, inputs, 1)
        if x.dim() != 4 or len(size) != 2 or min(size) < 1 or min(x.shape[1:3]) < 1:
            raise NodeError(f"ResizeBilinear of {list(x.shape)} to {size}")
        check_size([x.shape[0], *size, x.shape[3]], "the resized image")
        rows = _source_rows(size[0], x.shape[1], align, half, x.device)
        cols = _source_rows(size[1], x.shape[2], align, half, x.device)
        wide = x.double()
        row_fraction = rows[2].reshape(1, -1, 1, 1)
        column_fraction = cols[2].reshape(1, 1, -1, 1)

        def interpolated_columns(picked_rows: torch.Tensor) -> torch.Tensor:
            left, right = picked_rows[:, :, cols[0]], picked_rows[:, :, cols[1]]
            return left + (right - left) * column_fraction

        top = interpolated_columns(wide[:, rows[0]])
        bottom = interpolated_columns(wide[:, rows[1]])
        return ((top + (bottom - top) * row_fraction).to(x.dtype),)

    return PreparedOp(run, absorbed=absorbed_where((1, size_fixed)))


@register("AvgPool")
def _average_pool(node: GraphNode, constants: list[torch.Tensor | None]) -> PreparedOp:
    """``x (N,H,W,C) -> the mean over each window``; with SAME padding the mean is over the
    window's pixels inside the image (TF's rule)."""
    expect_inputs(node, 1)
    _check_nhwc(node)
    window, strides = _spatial(node, "ksize"), _spatial(node, "strides")
    pads = _window_padding(node)

    def run(inputs, params):
        x = inputs[0]
        if x.dim() != 4:
            raise NodeError(f"AvgPool of shape {list(x.shape)}, not NHWC")
        top, bottom, left, right = pads(x.shape[1], x.shape[2], *window, *strides, 1, 1)
        images = functional.pad(x.permute(0, 3, 1, 2), (left, right, top, bottom))
        ones = functional.pad(x.new_ones(1, 1, *x.shape[1:3]), (left, right, top, bottom))
        sums = functional.avg_pool2d(images, window, strides, divisor_override=1)
        counts = functional.avg_pool2d(ones, window, strides, divisor_override=1)
        return ((sums / counts).permute(0, 2, 3, 1),)

    return PreparedOp(run)

"""TF.js's CPU backend's float32 rounding, emulated in torch (tests/test_model_runtime_parity.py).

TF.js (``@tensorflow/tfjs-backend-cpu`` 4.22.0) accumulates a convolution output in a
``Float32Array``: ``y += x·w`` for each kernel row, column and input channel in that order,
each step computed in float64 (JavaScript numbers) and rounded to float32 when stored; a
depthwise convolution likewise over kernel rows and columns. Its ``LeakyRelu`` multiplies by
``alpha`` as a float64 (TF rounds alpha to float32 first). hkpd's runtime uses torch's fast
kernels instead, whose summation order differs, so its outputs differ from TF.js's by float32
rounding only; with these replacements every other op's semantics can be checked to the last
bits. ``tfjs_rounding(monkeypatch)`` installs them into the runtime's op modules.
"""

from __future__ import annotations

import types

import pytest
import torch
import torch.nn.functional as functional

from hkpd.model_runtime import ops_math, ops_nn


def _windows(x: torch.Tensor, row: int, column: int, shape: tuple, stride, dilation):
    """The input pixels kernel tap (row, column) meets for each output pixel: ``(N, C, Ho, Wo)``."""
    height, width = shape
    top, left = row * dilation[0], column * dilation[1]
    return x[
        :,
        :,
        top : top + (height - 1) * stride[0] + 1 : stride[0],
        left : left + (width - 1) * stride[1] + 1 : stride[1],
    ]


def tfjs_conv2d(x, weight, bias, stride, padding, dilation, groups):
    """``functional.conv2d``'s arguments (NCHW, weight (O, I, kh, kw)), TF.js's rounding."""
    images = functional.pad(x, (padding[1], padding[1], padding[0], padding[0])).double()
    batch, channels, height, width = images.shape
    outputs, _, kernel_h, kernel_w = weight.shape
    out_h = (height - (kernel_h - 1) * dilation[0] - 1) // stride[0] + 1
    out_w = (width - (kernel_w - 1) * dilation[1] - 1) // stride[1] + 1
    total = torch.zeros(batch, outputs, out_h, out_w, dtype=torch.float64)
    taps = weight.double()
    if groups != 1:  # depthwise: output channel o reads input channel o // multiplier
        images = images.repeat_interleave(outputs // channels, dim=1)
    for row in range(kernel_h):
        for column in range(kernel_w):
            window = _windows(images, row, column, (out_h, out_w), stride, dilation)
            if groups != 1:
                tap = taps[:, 0, row, column].reshape(1, outputs, 1, 1)
                total = (total + window * tap).float().double()
                continue
            for channel in range(channels):
                tap = taps[:, channel, row, column].reshape(1, outputs, 1, 1)
                total = (total + window[:, channel : channel + 1] * tap).float().double()
    result = total.float()
    return result if bias is None else result + bias.reshape(1, -1, 1, 1)


def tfjs_leaky_relu(x: torch.Tensor, alpha: float) -> torch.Tensor:
    """TF.js's ``x < 0 ? alpha·x : x`` with alpha a float64."""
    return torch.where(x < 0, (x.double() * alpha).float(), x)


def _functional_with(**replacements) -> types.SimpleNamespace:
    names = {name: getattr(functional, name) for name in dir(functional) if name[:2] != "__"}
    return types.SimpleNamespace(**(names | replacements))


def tfjs_rounding(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the runtime's convolutions and LeakyRelu round as TF.js's CPU backend does."""
    patched = _functional_with(conv2d=tfjs_conv2d, leaky_relu=tfjs_leaky_relu)
    monkeypatch.setattr(ops_nn, "functional", patched)
    monkeypatch.setattr(ops_math, "functional", patched)

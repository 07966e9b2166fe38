"""A ResNet-style image backbone (He et al. 2016) in plain torch, with a width multiplier.

``ResNetBackbone(base_width=64, blocks=(2, 2, 2, 2))`` is ResNet-18's convolutional trunk; the
network maps ``(B, C, H, W)`` inputs to ``(B, 8 × base_width)`` globally average-pooled features.
Smaller ``base_width`` (32, 16) scales every layer's channels, for training on a CPU.

The convolutions run in the channels-last (NHWC) memory layout: on the development VM's CPU
(2 threads, ResNet-18, batch 16 at 256 px) that made inference 1.5x and a training step
(forward + backward) 4x faster than the default NCHW layout. Inputs in either layout are
accepted; weights are kept channels-last (``Module.to`` and ``load_state_dict`` preserve that).

Backbones narrower than ``CHANNELS_LAST_MIN_WIDTH`` (the tiny networks of tests and smoke runs)
stay in NCHW: torch 2.13's CPU kernel (oneDNN 3.12, AVX2) for the weight gradient of a
channels-last 1×1 strided convolution with fewer than 8 input channels, the shortcut
projection of such a backbone, writes out of bounds. With two threads the gradient comes out
wrong and different on every call (half its magnitude off); with one thread glibc aborts on
the corrupted heap (``tests/test_network_model.py`` checks a narrow backbone's gradient).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

CHANNELS_LAST_MIN_WIDTH = 8
"""The narrowest ``base_width`` that runs channels-last (see the module docstring)."""


class BasicBlock(nn.Module):
    """Two 3×3 convolutions with batch norm and an identity (or 1×1 projection) shortcut.

    Args:
        in_channels, out_channels: channel counts.
        stride: stride of the first convolution (2 halves the resolution).
    """

    def __init__(self, in_channels: int, out_channels: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(out_channels)
        self.conv2 = nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(out_channels)
        self.shortcut: nn.Module = nn.Identity()
        if stride != 1 or in_channels != out_channels:
            self.shortcut = nn.Sequential(
                nn.Conv2d(in_channels, out_channels, 1, stride, bias=False),
                nn.BatchNorm2d(out_channels),
            )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, in, H, W)`` to ``(B, out, H / stride, W / stride)``."""
        out = torch.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return torch.relu(out + self.shortcut(x))


class ResNetBackbone(nn.Module):
    """ResNet stem, four stages of basic blocks and global average pooling.

    Args:
        in_channels: input channels (18 for the proxy representation).
        base_width: channels of the first stage; stage k has ``base_width × 2^k``.
        blocks: number of basic blocks per stage (``(2, 2, 2, 2)`` = ResNet-18).

    Attributes:
        feature_dim: size of the output feature vector, ``base_width × 2^(len(blocks) - 1)``.
    """

    def __init__(
        self, in_channels: int = 18, base_width: int = 64, blocks: Sequence[int] = (2, 2, 2, 2)
    ) -> None:
        super().__init__()
        self.stem = nn.Sequential(
            nn.Conv2d(in_channels, base_width, 7, 2, 3, bias=False),
            nn.BatchNorm2d(base_width),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(3, 2, 1),
        )
        stages = []
        channels = base_width
        for index, count in enumerate(blocks):
            width = base_width * 2**index
            stride = 1 if index == 0 else 2
            layers = [BasicBlock(channels, width, stride)]
            layers += [BasicBlock(width, width) for _ in range(count - 1)]
            stages.append(nn.Sequential(*layers))
            channels = width
        self.stages = nn.Sequential(*stages)
        self.feature_dim = channels
        self._initialise()
        self.memory_format = (
            torch.channels_last
            if base_width >= CHANNELS_LAST_MIN_WIDTH
            else torch.contiguous_format
        )
        self.to(memory_format=self.memory_format)

    def _initialise(self) -> None:
        for module in self.modules():
            if isinstance(module, nn.Conv2d):
                nn.init.kaiming_normal_(module.weight, mode="fan_out", nonlinearity="relu")
            elif isinstance(module, nn.BatchNorm2d):
                nn.init.ones_(module.weight)
                nn.init.zeros_(module.bias)
        # Each residual branch starts as zero, so every block starts as the identity: this makes
        # the first steps of training better conditioned (Goyal et al. 2017).
        for module in self.modules():
            if isinstance(module, BasicBlock):
                nn.init.zeros_(module.bn2.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, in_channels, H, W)`` images to ``(B, feature_dim)`` pooled features."""
        x = x.contiguous(memory_format=self.memory_format)
        return self.stages(self.stem(x)).mean(dim=(-2, -1))

"""``GroupedLinear``: G independent linear layers applied in one batched product.

The hierarchical head gives every joint its own fully connected stream; the joints at one depth
of the kinematic tree are evaluated together, each with its own weights, by one ``einsum``
instead of a Python loop over joints.
"""

from __future__ import annotations

import math

import torch
from torch import nn


class GroupedLinear(nn.Module):
    """``y[:, g] = x[:, g] @ W[g] + b[g]`` for groups ``g = 0 .. G-1``.

    Args:
        groups: number of independent layers G.
        in_features, out_features: sizes of each layer.
        bias: whether to add a per-group bias.

    Weights are initialised like :class:`torch.nn.Linear` (uniform in ``±1/sqrt(in)``).
    """

    def __init__(self, groups: int, in_features: int, out_features: int, bias: bool = True):
        super().__init__()
        self.groups = groups
        self.in_features = in_features
        self.out_features = out_features
        bound = 1.0 / math.sqrt(max(in_features, 1))
        self.weight = nn.Parameter(
            torch.empty(groups, in_features, out_features).uniform_(-bound, bound)
        )
        self.bias = (
            nn.Parameter(torch.empty(groups, out_features).uniform_(-bound, bound))
            if bias
            else None
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, G, in_features)`` to ``(B, G, out_features)``."""
        if x.shape[-2:] != (self.groups, self.in_features):
            raise ValueError(
                f"GroupedLinear expects (B, {self.groups}, {self.in_features}), "
                f"got {tuple(x.shape)}"
            )
        # (G, B, in) @ (G, in, out): one batched matrix product.
        y = torch.bmm(x.transpose(0, 1), self.weight).transpose(0, 1)
        return y if self.bias is None else y + self.bias

    def extra_repr(self) -> str:
        return (
            f"groups={self.groups}, in_features={self.in_features}, "
            f"out_features={self.out_features}, bias={self.bias is not None}"
        )

"""Post-hoc concentration scaling: evaluate a network as if its pose distributions were
sharper or wider.

Multiplying every matrix-Fisher parameter ``F_i`` by a factor ``t > 0`` keeps each joint's mode
(the proper SVD's ``U V^T`` does not change) and scales its concentration: ``t = 0.25`` roughly
doubles the angular spread of the samples, ``t = 4`` halves it. This is temperature scaling for
rotations, the same as :meth:`KinematicMatrixFisher.scale_concentration` on all 23 joints, which
the explorer's "All joints" slider applies (``10 ** slider``); here it acts on the network's
output, so every evaluation downstream sees the scaled F. It lets
``hkpd-eval`` measure the trade-off between the samples' 2D error and calibration for a trained
model without retraining it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import torch

from hkpd.distributions import BodyDistribution


class ConcentrationScaled(torch.nn.Module):
    """Wrap a distribution network so that its predicted ``F`` is multiplied by ``factor``.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (or anything returning a
            :class:`BodyDistribution` for a ``(B, C, S, S)`` proxy).
        factor: the positive, finite scale applied to every ``(B, 23, 3, 3)`` F.

    Attributes:
        config: the wrapped network's ``config``.
    """

    def __init__(self, network: torch.nn.Module, factor: float) -> None:
        super().__init__()
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"the concentration scale must be a positive number, got {factor}")
        self.network = network
        self.config = network.config
        self.factor = float(factor)

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        output = self.network(proxy)
        return replace(output, F=output.F * self.factor)

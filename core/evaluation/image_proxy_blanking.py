"""How much a network reads its image proxy: the same inputs with the image channels blanked.

:class:`WithoutImageProxy` wraps a distribution network and zeroes the image part of every
proxy it is given (no edges, an empty silhouette, a black RGB crop) while the 17 joint heatmaps
stay. Scored against the untouched network, it says what the image channels are worth on a
given set: on real photos the shipped edge network's error barely moved when its edges were
removed (issue 21), which is the question the proxy ablation asks of each proxy.
"""

from __future__ import annotations

import torch

from hkpd.distributions import BodyDistribution
from hkpd.proxy import NUM_KEYPOINTS


class WithoutImageProxy(torch.nn.Module):
    """Wrap a distribution network so that it sees only the joint heatmaps of its input.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (its ``config`` is passed on, so a
            :class:`hkpd.prediction.Predictor` can use the wrapper as its network).
    """

    def __init__(self, network: torch.nn.Module) -> None:
        super().__init__()
        self.network = network
        self.config = network.config

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        """The network's output for ``(B, C + 17, S, S)`` proxies whose first ``C`` channels
        are set to zero (the caller's tensor is left as it is)."""
        blanked = proxy.clone()
        blanked[:, : proxy.shape[1] - NUM_KEYPOINTS] = 0.0
        return self.network(blanked)

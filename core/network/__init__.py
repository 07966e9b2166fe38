"""The distribution-prediction network: a ResNet-style backbone over the proxy and independent or
hierarchical matrix-Fisher pose heads, plus shape, global-rotation and camera heads.

- :class:`DistributionNetwork` (built from a :class:`NetworkConfig`) maps ``(B, 18, H, W)`` proxies
  to a :class:`hkpd.distributions.BodyDistribution`, whose ``pose_distribution()`` and
  ``shape_distribution()`` give the predicted distributions.
"""

from hkpd.network.backbone import BasicBlock, ResNetBackbone
from hkpd.network.config import POSE_HEADS, NetworkConfig
from hkpd.network.grouped_linear import GroupedLinear
from hkpd.network.hierarchical_head import HierarchicalHead
from hkpd.network.independent_head import IndependentHead
from hkpd.network.model import DistributionNetwork

__all__ = [
    "POSE_HEADS",
    "BasicBlock",
    "DistributionNetwork",
    "GroupedLinear",
    "HierarchicalHead",
    "IndependentHead",
    "NetworkConfig",
    "ResNetBackbone",
]

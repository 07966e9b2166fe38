"""``DistributionNetwork``: proxy representation in, pose and shape distributions out."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import torch
from torch import nn

from hkpd.distributions import BodyDistribution
from hkpd.kinematic_tree import BODY_PARENTS
from hkpd.network.backbone import ResNetBackbone
from hkpd.network.config import NetworkConfig
from hkpd.network.hierarchical_head import HierarchicalHead
from hkpd.network.independent_head import IndependentHead


class DistributionNetwork(nn.Module):
    """ResNet backbone plus an independent or hierarchical distribution head.

    Args:
        config: the architecture; None = :class:`NetworkConfig` defaults (ResNet-18,
            hierarchical head, 256-pixel input).

    Attributes:
        config: the :class:`NetworkConfig` (store ``config.to_dict()`` in checkpoints).
        backbone: :class:`hkpd.network.backbone.ResNetBackbone`.
        head: :class:`IndependentHead` or :class:`HierarchicalHead`.
        log_concentration_scale: ``(23,)`` buffer: each joint's final ``F`` is multiplied by
            ``exp`` of its entry (zeros, i.e. unchanged, unless the weights were calibrated by
            :mod:`hkpd.training.calibrate_concentration`). It acts after the head, so the
            hierarchical head's children still read their ancestors' uncalibrated ``F``, and
            it keeps every joint's mode. Checkpoints written before it existed load with zeros.
    """

    def __init__(self, config: NetworkConfig | None = None) -> None:
        super().__init__()
        self.config = NetworkConfig() if config is None else config
        c = self.config
        self.backbone = ResNetBackbone(c.input_channels, c.backbone_base_width, c.backbone_blocks)
        initial = {
            "initial_pose_concentration": c.initial_pose_concentration,
            "initial_shape_std": c.initial_shape_std,
            "initial_camera_scale": c.initial_camera_scale,
            "concentration_gain": c.concentration_gain,
        }
        self.head: nn.Module
        if c.pose_head == "independent":
            self.head = IndependentHead(
                self.backbone.feature_dim, c.head_hidden, c.num_betas, len(BODY_PARENTS), **initial
            )
        else:
            self.head = HierarchicalHead(
                self.backbone.feature_dim,
                c.head_hidden,
                c.joint_hidden,
                c.num_betas,
                BODY_PARENTS,
                **initial,
            )
        self.register_buffer("log_concentration_scale", torch.zeros(len(BODY_PARENTS)))

    @classmethod
    def from_config(cls, config: NetworkConfig | dict[str, Any]) -> DistributionNetwork:
        """A freshly initialised network from a config or its ``to_dict()`` form."""
        if isinstance(config, dict):
            config = NetworkConfig.from_dict(config)
        return cls(config)

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        """Predict distributions for a batch of proxy representations.

        Args:
            proxy: ``(B, input_channels, image_size, image_size)`` float (see
                :mod:`hkpd.proxy.representation`).

        Returns:
            :class:`BodyDistribution` with batch size B.

        Raises:
            ValueError: if the input's shape does not match the config.
        """
        self._check_input(proxy)
        output = self.head(self.backbone(proxy))
        scale = self.log_concentration_scale.exp().to(output.F.dtype)
        return replace(output, F=output.F * scale[:, None, None])

    def _check_input(self, proxy: torch.Tensor) -> None:
        c = self.config
        expected = (c.input_channels, c.image_size, c.image_size)
        if not isinstance(proxy, torch.Tensor) or not proxy.is_floating_point():
            raise TypeError("proxy must be a floating-point torch.Tensor of shape (B, C, H, W)")
        if proxy.dim() != 4 or tuple(proxy.shape[1:]) != expected:
            raise ValueError(
                f"proxy must have shape (B, {', '.join(map(str, expected))}) for this network "
                f"(config.input_channels={c.input_channels}, config.image_size={c.image_size}), "
                f"got {tuple(proxy.shape)}"
            )
        if proxy.shape[0] < 1:
            raise ValueError("proxy batch is empty")

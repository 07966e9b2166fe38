"""The independent head f_indep (paper Eq. 4): one FC stream predicts every output at once."""

from __future__ import annotations

import torch
from torch import nn

from hkpd.distributions import BodyDistribution
from hkpd.network.output_decoding import decode_globals, decode_pose, global_bias, global_size

OUTPUT_WEIGHT_SCALE = 0.1
"""Final layers start with weights this much smaller than the default, so that the initial
predictions sit near the decoding biases (see :mod:`hkpd.network.output_decoding`)."""


def init_output_layer(layer: nn.Module, bias: torch.Tensor | None = None) -> None:
    """Shrink a final layer's weights by :data:`OUTPUT_WEIGHT_SCALE` and set its bias."""
    with torch.no_grad():
        layer.weight.mul_(OUTPUT_WEIGHT_SCALE)
        if layer.bias is not None:
            layer.bias.copy_(torch.zeros_like(layer.bias) if bias is None else bias)


def globals_output_layer(
    hidden: int, num_betas: int, initial_shape_std: float, initial_camera_scale: float
) -> nn.Linear:
    """The final layer of the global outputs (shape mean and std, global rotation, camera;
    :func:`hkpd.network.output_decoding.decode_globals`), started at the decoding biases."""
    layer = nn.Linear(hidden, global_size(num_betas))
    init_output_layer(layer, global_bias(num_betas, initial_shape_std, initial_camera_scale))
    return layer


def zero_layer(layer: nn.Module) -> None:
    """Set a layer's weights and bias to zero (a new output that starts as a no-op)."""
    for parameter in layer.parameters():
        nn.init.zeros_(parameter)


class IndependentHead(nn.Module):
    """Two hidden FC layers, then linear outputs for all 23 joints' ``F`` and the global outputs.

    Each joint's ``F_i`` depends on the image features only, so joints are modelled
    independently of their parents.

    Args:
        feature_dim: size of the backbone features.
        hidden: width of the two hidden layers.
        num_betas: shape coefficients K.
        num_joints: body joints (23).
        initial_pose_concentration, initial_shape_std, initial_camera_scale: initial values of
            the decoded outputs (see :class:`hkpd.network.NetworkConfig`).
        concentration_gain: also predict a log-gain per joint (see
            :func:`hkpd.network.output_decoding.decode_pose`).
    """

    def __init__(
        self,
        feature_dim: int,
        hidden: int,
        num_betas: int,
        num_joints: int,
        initial_pose_concentration: float,
        initial_shape_std: float,
        initial_camera_scale: float,
        concentration_gain: bool = False,
    ) -> None:
        super().__init__()
        self.num_betas = num_betas
        self.num_joints = num_joints
        self.concentration = initial_pose_concentration
        self.trunk = nn.Sequential(
            nn.Linear(feature_dim, hidden),
            nn.ReLU(inplace=True),
            nn.Linear(hidden, hidden),
            nn.ReLU(inplace=True),
        )
        self.globals_out = globals_output_layer(
            hidden, num_betas, initial_shape_std, initial_camera_scale
        )
        self.pose_out = nn.Linear(hidden, num_joints * 9)
        init_output_layer(self.pose_out)
        self.log_gain_out = nn.Linear(hidden, num_joints) if concentration_gain else None
        if self.log_gain_out is not None:
            zero_layer(self.log_gain_out)

    def forward(self, features: torch.Tensor) -> BodyDistribution:
        """``(B, feature_dim)`` image features to a :class:`BodyDistribution`."""
        embedding = self.trunk(features)
        mean, std, orient, camera = decode_globals(self.globals_out(embedding), self.num_betas)
        raw_pose = self.pose_out(embedding).unflatten(-1, (self.num_joints, 9))
        log_gain = None if self.log_gain_out is None else self.log_gain_out(embedding)
        F = decode_pose(raw_pose, self.concentration, log_gain)
        return BodyDistribution(F, mean, std, orient, camera)

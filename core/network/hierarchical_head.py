"""The hierarchical head f_hier (paper Eq. 6): each joint's ``F_i`` is conditioned on its
ancestors' distributions, the shape distribution, the global rotation and the camera.

First, shape mean/std, global rotation and camera are predicted from the image embedding. Then,
for each joint ``i``, an FC stream with its own weights maps

    [image embedding, shape mean, shape std, global rotation (9), camera (3),
     (U_j (9), S_j (3), R_mode_j (9)) for every ancestor j of i, root side first]

to ``F_i``. ``U_j, S_j, R_mode_j`` come from the proper SVD of the ancestors' predicted ``F_j``,
with gradients. The singular values enter as ``sign(s) log(1 + |s|)`` so that confident
(large-``s``) parents do not swamp the other inputs.

Joints at the same tree depth have the same number of ancestors and depend only on shallower
joints, so a depth level is evaluated at once: the part of every joint's first layer that acts
on the shared inputs is one ``Linear`` for all 23 joints (computed before the level loop), and the
ancestor inputs, hidden layers and outputs are :class:`GroupedLinear` layers (one weight matrix per
joint). The loop runs over the tree's 9 depth levels, not over joints.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from itertools import pairwise

import torch
from torch import nn

from hkpd.distributions import BodyDistribution, proper_svd
from hkpd.kinematic_tree import ancestors, depth_levels, validate_parents
from hkpd.network.grouped_linear import GroupedLinear
from hkpd.network.independent_head import globals_output_layer, init_output_layer, zero_layer
from hkpd.network.output_decoding import (
    decode_globals,
    decode_pose,
    full_precision,
)

ANCESTOR_FEATURES = 9 + 3 + 9
"""Per ancestor: principal axes U (flattened), proper singular values S, mode (flattened)."""

LevelEdit = Callable[[tuple[int, ...], torch.Tensor], torch.Tensor]
"""``edit(level_joints, F_level (B, n, 3, 3)) -> F_level``: a test hook that replaces a depth
level's ``F`` before its children see it."""


def ancestor_features(F: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` parameters to ``(..., 21)`` features ``[U, sign(S) log(1+|S|), U V^T]``.

    Computed in full precision even under ``torch.autocast``.
    """
    with torch.autocast(F.device.type, enabled=False):
        U, S, V = proper_svd(full_precision(F))
        mode = U @ V.transpose(-1, -2)
        squashed = torch.sign(S) * torch.log1p(S.abs())
        return torch.cat((U.flatten(-2), squashed, mode.flatten(-2)), dim=-1)


class _LevelStreams(nn.Module):
    """The per-joint layers of one depth level (``count`` joints with ``depth`` ancestors)."""

    def __init__(self, count: int, depth: int, hidden: Sequence[int], gain: bool) -> None:
        super().__init__()
        self.ancestor_in = (
            GroupedLinear(count, depth * ANCESTOR_FEATURES, hidden[0], bias=False)
            if depth > 0
            else None
        )
        self.hidden = nn.ModuleList(GroupedLinear(count, a, b) for a, b in pairwise(hidden))
        self.out = GroupedLinear(count, hidden[-1], 9)
        init_output_layer(self.out)
        self.log_gain = GroupedLinear(count, hidden[-1], 1) if gain else None
        if self.log_gain is not None:
            zero_layer(self.log_gain)

    def forward(
        self, first: torch.Tensor, ancestors_in: torch.Tensor | None
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """First-layer pre-activations ``(B, n, h0)`` and ancestor inputs to raw ``(B, n, 9)``
        outputs and, with a concentration gain, ``(B, n, 1)`` log-gains (else None)."""
        if self.ancestor_in is not None and ancestors_in is not None:
            first = first + self.ancestor_in(ancestors_in)
        x = torch.relu(first)
        for layer in self.hidden:
            x = torch.relu(layer(x))
        return self.out(x), (None if self.log_gain is None else self.log_gain(x))


class HierarchicalHead(nn.Module):
    """The hierarchical matrix-Fisher head (see the module docstring).

    Args:
        feature_dim: size of the backbone features.
        hidden: width of the shared FC layer on the image features (the "image embedding").
        joint_hidden: hidden widths of each joint's FC stream.
        num_betas: shape coefficients K.
        parents: the body joints' parents (:data:`hkpd.kinematic_tree.BODY_PARENTS`).
        initial_pose_concentration, initial_shape_std, initial_camera_scale: initial values of
            the decoded outputs (see :class:`hkpd.network.NetworkConfig`).
        concentration_gain: give each joint stream a log-gain output (see
            :func:`hkpd.network.output_decoding.decode_pose`).

    Attributes:
        detach_shape_input: feed the joint streams the shape mean and std *detached* (same
            values, no gradient), so that losses on the pose cannot move the shape outputs
            through the streams' inputs; set by training with ``--shape-from-nll-only``.
            Off by default (the paper's f_hier trains both through this path).
    """

    def __init__(
        self,
        feature_dim: int,
        hidden: int,
        joint_hidden: Sequence[int],
        num_betas: int,
        parents: Sequence[int],
        initial_pose_concentration: float,
        initial_shape_std: float,
        initial_camera_scale: float,
        concentration_gain: bool = False,
    ) -> None:
        super().__init__()
        self.parents = validate_parents(parents)
        self.num_betas = num_betas
        self.num_joints = len(self.parents)
        self.concentration = initial_pose_concentration
        self.detach_shape_input = False
        self.levels: tuple[tuple[int, ...], ...] = tuple(
            tuple(level) for level in depth_levels(self.parents)
        )
        order = [joint for level in self.levels for joint in level]
        position = {joint: index for index, joint in enumerate(order)}

        self.trunk = nn.Sequential(nn.Linear(feature_dim, hidden), nn.ReLU(inplace=True))
        self.globals_out = globals_output_layer(
            hidden, num_betas, initial_shape_std, initial_camera_scale
        )
        shared_inputs = hidden + 2 * num_betas + 9 + 3
        # Rows grouped by joint in processing order, so each level is a contiguous slice.
        self.first_layer = nn.Linear(shared_inputs, self.num_joints * joint_hidden[0])
        self.level_streams = nn.ModuleList(
            _LevelStreams(len(level), depth, joint_hidden, concentration_gain)
            for depth, level in enumerate(self.levels)
        )
        for depth, level in enumerate(self.levels):
            # Each joint's ancestors, root side first: (count × depth) rows of the known features.
            rows = [
                position[a] for joint in level for a in reversed(ancestors(self.parents, joint))
            ]
            self.register_buffer(f"_ancestor_rows_{depth}", torch.tensor(rows), persistent=False)
        inverse = torch.tensor([position[joint] for joint in range(self.num_joints)])
        self.register_buffer("_joint_order", inverse, persistent=False)
        self._first_hidden = joint_hidden[0]

    def forward(self, features: torch.Tensor) -> BodyDistribution:
        """``(B, feature_dim)`` image features to a :class:`BodyDistribution`."""
        return self.predict(features)

    def predict(self, features: torch.Tensor, edit: LevelEdit | None = None) -> BodyDistribution:
        """Like :meth:`forward`; ``edit`` (tests only) may replace each level's ``F``."""
        embedding = self.trunk(features)
        mean, std, orient, camera = decode_globals(self.globals_out(embedding), self.num_betas)
        mean_in, std_in = (mean.detach(), std.detach()) if self.detach_shape_input else (mean, std)
        shared = torch.cat((embedding, mean_in, std_in, orient.flatten(-2), camera), dim=-1)
        return BodyDistribution(self.pose_parameters(shared, edit), mean, std, orient, camera)

    def pose_parameters(self, shared: torch.Tensor, edit: LevelEdit | None = None) -> torch.Tensor:
        """All joints' ``F`` from the shared inputs, level by level down the tree.

        Args:
            shared: ``(B, hidden + 2K + 12)`` image embedding, shape mean and std, flattened
                global rotation and camera.
            edit: optional hook applied to each level's ``F`` before its children use it.

        Returns:
            ``(B, 23, 3, 3)`` in joint order.
        """
        batch = shared.shape[0]
        first_all = self.first_layer(shared).view(batch, self.num_joints, self._first_hidden)
        level_F: list[torch.Tensor] = []
        level_features: list[torch.Tensor] = []
        start = 0
        for depth, (level, streams) in enumerate(zip(self.levels, self.level_streams, strict=True)):
            count = len(level)
            ancestors_in = None
            if depth > 0:
                known = torch.cat(level_features, dim=1)  # (B, joints so far, 21)
                rows = getattr(self, f"_ancestor_rows_{depth}")
                ancestors_in = known.index_select(1, rows).reshape(batch, count, -1)
            raw, log_gain = streams(first_all[:, start : start + count], ancestors_in)
            F = decode_pose(raw, self.concentration, log_gain)
            if edit is not None:
                F = edit(level, F)
            level_F.append(F)
            if depth + 1 < len(self.levels):
                level_features.append(ancestor_features(F))
            start += count
        return torch.cat(level_F, dim=1).index_select(1, self._joint_order)

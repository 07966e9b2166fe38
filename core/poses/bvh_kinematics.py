"""Rotations and forward kinematics of a parsed BVH motion.

BVH convention: a joint's channels are applied in the order written, each about the joint's own
(already rotated) axes, so ``CHANNELS 3 Zrotation Xrotation Yrotation`` means the local rotation
``R = Rz(z) @ Rx(x) @ Ry(y)``. In the rest pose (all channels zero) every joint frame is parallel
to the world frame, and a joint sits at its parent's position plus the parent's global rotation
applied to its ``OFFSET``.
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.poses.bvh import BvhMotion, BvhSkeleton


def axis_rotation(axis: str, degrees: torch.Tensor) -> torch.Tensor:
    """Rotation matrices about a coordinate axis.

    Args:
        axis: ``"X"``, ``"Y"`` or ``"Z"``.
        degrees: ``(...)`` angles in degrees (right-handed, counter-clockwise looking down the
            axis).

    Returns:
        ``(..., 3, 3)`` rotation matrices, same dtype as ``degrees``.
    """
    radians = torch.deg2rad(degrees)
    cos, sin = torch.cos(radians), torch.sin(radians)
    one, zero = torch.ones_like(cos), torch.zeros_like(cos)
    if axis == "X":
        rows = [[one, zero, zero], [zero, cos, -sin], [zero, sin, cos]]
    elif axis == "Y":
        rows = [[cos, zero, sin], [zero, one, zero], [-sin, zero, cos]]
    elif axis == "Z":
        rows = [[cos, -sin, zero], [sin, cos, zero], [zero, zero, one]]
    else:
        raise ValueError(f"axis must be 'X', 'Y' or 'Z', not {axis!r}")
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def local_rotations(motion: BvhMotion) -> torch.Tensor:
    """Each joint's rotation relative to its parent, frame by frame.

    Returns:
        ``(F, J, 3, 3)`` float64; identity for end sites and joints without rotation channels.
    """
    skeleton = motion.skeleton
    frames = torch.from_numpy(motion.frames)
    num_frames = frames.shape[0]
    rotations = torch.eye(3, dtype=torch.float64).repeat(num_frames, skeleton.num_joints, 1, 1)
    column = 0
    for joint, joint_channels in enumerate(skeleton.channels):
        for channel in joint_channels:
            if channel.endswith("rotation"):
                rotations[:, joint] = rotations[:, joint] @ axis_rotation(
                    channel[0], frames[:, column]
                )
            column += 1
    return rotations


def joint_translations(motion: BvhMotion) -> torch.Tensor:
    """Each joint's translation from its parent in the parent's frame: OFFSET plus any position
    channels (normally only the root has those).

    Returns:
        ``(F, J, 3)`` float64 in the file's length unit.
    """
    skeleton = motion.skeleton
    frames = torch.from_numpy(motion.frames)
    translations = torch.from_numpy(skeleton.offsets).repeat(frames.shape[0], 1, 1)
    column = 0
    for joint, joint_channels in enumerate(skeleton.channels):
        for channel in joint_channels:
            if channel.endswith("position"):
                axis = "XYZ".index(channel[0])
                translations[:, joint, axis] = translations[:, joint, axis] + frames[:, column]
            column += 1
    return translations


def forward_kinematics(
    skeleton: BvhSkeleton, rotations: torch.Tensor, translations: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Global joint rotations and positions.

    Args:
        skeleton: the hierarchy (parents before children).
        rotations: ``(F, J, 3, 3)`` local rotations.
        translations: ``(F, J, 3)`` local translations; default: the skeleton's offsets (root
            at the origin).

    Returns:
        ``global_rotations (F, J, 3, 3)`` (joint frame to world) and ``positions (F, J, 3)`` in
        the file's length unit.
    """
    if translations is None:
        offsets = torch.from_numpy(np.asarray(skeleton.offsets)).to(rotations.dtype)
        translations = offsets.expand(rotations.shape[0], -1, -1)
    global_rotations: list[torch.Tensor] = []
    positions: list[torch.Tensor] = []
    for joint, parent in enumerate(skeleton.parents):
        if parent < 0:
            global_rotations.append(rotations[:, joint])
            positions.append(translations[:, joint])
        else:
            parent_rotation = global_rotations[parent]
            global_rotations.append(parent_rotation @ rotations[:, joint])
            positions.append(
                positions[parent] + (parent_rotation @ translations[:, joint, :, None])[..., 0]
            )
    return torch.stack(global_rotations, dim=1), torch.stack(positions, dim=1)

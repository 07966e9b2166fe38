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

from hkpd.kinematic_tree import depth_levels
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
    num_frames = motion.frames.shape[0]
    # Column, axis and position-within-joint of every rotation channel.
    columns: list[int] = []
    axes: list[int] = []
    joints: list[int] = []
    slots: list[int] = []
    column = 0
    for joint, joint_channels in enumerate(skeleton.channels):
        slot = 0
        for channel in joint_channels:
            if channel.endswith("rotation"):
                columns.append(column)
                axes.append("XYZ".index(channel[0]))
                joints.append(joint)
                slots.append(slot)
                slot += 1
            column += 1
    rotations = np.broadcast_to(np.eye(3), (num_frames, skeleton.num_joints, 3, 3)).copy()
    if not columns:
        return torch.from_numpy(rotations)
    radians = np.deg2rad(motion.frames[:, columns])
    cos, sin = np.cos(radians), np.sin(radians)
    elementary = np.zeros((num_frames, len(columns), 3, 3))
    for axis in range(3):
        picked = np.asarray(axes) == axis
        first, second = [a for a in range(3) if a != axis]
        # Right-handed rotation about `axis`: the plane (first, second) turns counter-clockwise,
        # with the sine's sign flipped for Y (whose plane is (Z, X)).
        sign = -1.0 if axis == 1 else 1.0
        block = elementary[:, picked]
        block[..., axis, axis] = 1.0
        block[..., first, first] = cos[:, picked]
        block[..., second, second] = cos[:, picked]
        block[..., first, second] = -sign * sin[:, picked]
        block[..., second, first] = sign * sin[:, picked]
        elementary[:, picked] = block
    # Multiply each joint's channels in file order, all joints of one slot at a time.
    joints_array, slots_array = np.asarray(joints), np.asarray(slots)
    for slot in range(int(slots_array.max()) + 1):
        chosen = np.nonzero(slots_array == slot)[0]
        targets = joints_array[chosen]
        rotations[:, targets] = rotations[:, targets] @ elementary[:, chosen]
    return torch.from_numpy(rotations)


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
        the file's length unit, same dtype as ``rotations``.
    """
    local = rotations.detach().cpu().numpy()
    if translations is None:
        offsets = np.broadcast_to(skeleton.offsets, (local.shape[0], *skeleton.offsets.shape))
    else:
        offsets = translations.detach().cpu().numpy()
    global_rotations = np.empty_like(local)
    positions = np.empty((*local.shape[:2], 3), dtype=local.dtype)
    # Whole tree levels at once (numpy's stacked 3x3 products are much faster than torch's).
    for level in depth_levels(skeleton.parents):
        level_parents = [skeleton.parents[j] for j in level]
        if level_parents[0] < 0:
            global_rotations[:, level] = local[:, level]
            positions[:, level] = offsets[:, level]
            continue
        parent_rotations = global_rotations[:, level_parents]
        global_rotations[:, level] = parent_rotations @ local[:, level]
        positions[:, level] = (
            positions[:, level_parents] + (parent_rotations @ offsets[:, level, :, None])[..., 0]
        )
    return (
        torch.from_numpy(global_rotations).to(rotations.dtype),
        torch.from_numpy(positions).to(rotations.dtype),
    )

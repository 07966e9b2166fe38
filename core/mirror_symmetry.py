"""Left/right mirroring of SMPL poses across the body's sagittal plane (x -> -x in SMPL axes).

Shared by the pose bank (mirrored training poses, :mod:`hkpd.poses.bank_builder`) and the
prediction (reading the mirror image of a photo, :mod:`hkpd.prediction.readings.mirror`), so it
sits next to the kinematic tree, below both."""

from __future__ import annotations

import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES

# M @ R @ M with M = diag(-1, 1, 1) flips the sign of the entries (i, j) with m_i * m_j = -1.
_REFLECTION_SIGNS = torch.tensor([[1.0, -1.0, -1.0], [-1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])


def _swapped_name(name: str) -> str:
    if name.startswith("left_"):
        return "right_" + name[5:]
    if name.startswith("right_"):
        return "left_" + name[6:]
    return name


BODY_MIRROR_PERMUTATION: tuple[int, ...] = tuple(
    BODY_JOINT_NAMES.index(_swapped_name(n)) for n in BODY_JOINT_NAMES
)
"""``BODY_MIRROR_PERMUTATION[j]`` is the body joint whose rotation joint j takes when mirroring."""


def reflect_rotations(rotations: torch.Tensor) -> torch.Tensor:
    """Conjugate rotations by the reflection ``M = diag(-1, 1, 1)``: ``M @ R @ M``.

    Args:
        rotations: ``(..., 3, 3)`` rotation matrices in SMPL axes.

    Returns:
        ``(..., 3, 3)`` the mirror-image rotations (a rotation about axis (x, y, z) by angle a
        becomes a rotation about (x, -y, -z) by a).
    """
    return rotations * _REFLECTION_SIGNS.to(dtype=rotations.dtype, device=rotations.device)


def mirror_pose(
    body_pose: torch.Tensor, global_orient: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The left/right mirror image of SMPL poses.

    Args:
        body_pose: ``(..., 23, 3, 3)`` relative rotations of the body joints.
        global_orient: ``(..., 3, 3)`` root orientations.

    Returns:
        ``(body_pose, global_orient)`` mirrored: left and right joints swap their (reflected)
        rotations, and the root orientation is reflected. Applying it twice gives the input.
    """
    if body_pose.shape[-3:] != (23, 3, 3) or global_orient.shape[-2:] != (3, 3):
        raise ValueError(
            f"expected body_pose (..., 23, 3, 3) and global_orient (..., 3, 3), got "
            f"{tuple(body_pose.shape)} and {tuple(global_orient.shape)}"
        )
    permutation = torch.tensor(BODY_MIRROR_PERMUTATION, device=body_pose.device)
    return reflect_rotations(body_pose[..., permutation, :, :]), reflect_rotations(global_orient)

"""The SMPL 24-joint kinematic tree shared by the distributions, the body model and the network.

Joint 0 (``pelvis``) is the root; its rotation is the *global* rotation. The remaining 23 joints
are the *body* joints whose rotations, relative to their parents, make up the pose. Every parent
index is smaller than its child's, so iterating in index order visits parents first. It also holds
the tree's rotation arithmetic (:func:`compose_global_rotations`), which the distributions and the
body model share.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

SMPL_JOINT_NAMES: tuple[str, ...] = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hand",
    "right_hand",
)
"""Names of SMPL's 24 joints, in SMPL's order."""

SMPL_PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21,
)  # fmt: skip
"""Parent of each of the 24 SMPL joints (-1 for the root)."""

BODY_JOINT_NAMES: tuple[str, ...] = SMPL_JOINT_NAMES[1:]
"""Names of the 23 body (non-root) joints whose relative rotations form the pose."""

BODY_PARENTS: tuple[int, ...] = tuple(p - 1 for p in SMPL_PARENTS[1:])
"""Parent of each body joint, indexed among the 23 body joints; -1 means "the root (pelvis)"."""

LIMB_SEGMENT_PARTS: dict[str, tuple[str, ...]] = {
    f"{side}_{segment}": tuple(f"{side}_{part}" for part in parts)
    for side in ("left", "right")
    for segment, parts in (
        ("upper_arm", ("shoulder",)),
        ("forearm", ("elbow", "wrist", "hand")),
        ("thigh", ("hip",)),
        ("lower_leg", ("knee", "ankle", "foot")),
    )
}
"""The limb segments, as SMPL part groups (a part is named after the joint it starts at:
``left_elbow`` is the left forearm, ``left_hip`` the left thigh)."""


def validate_parents(parents: Sequence[int]) -> tuple[int, ...]:
    """Check that ``parents`` describes a kinematic forest in topological order.

    Args:
        parents: length-J sequence; ``parents[j]`` is the index of joint j's parent, or -1 when
            joint j hangs from the root frame.

    Returns:
        The parents as a tuple of ints.

    Raises:
        ValueError: if an entry is not -1 and not the index of an earlier joint.
    """
    checked = tuple(int(p) for p in parents)
    for joint, parent in enumerate(checked):
        if parent != -1 and not 0 <= parent < joint:
            raise ValueError(
                f"parents[{joint}] = {parent}: each parent must be -1 (the root) or the index of "
                "an earlier joint, so that parents come before their children."
            )
    return checked


def depth_levels(parents: Sequence[int]) -> list[list[int]]:
    """Group joints by their depth in the tree, so each level can be processed in one batch.

    Args:
        parents: a valid parents sequence (see :func:`validate_parents`).

    Returns:
        ``levels[d]`` lists the joints at depth d (depth 0 = joints whose parent is -1).
    """
    checked = validate_parents(parents)
    depth: list[int] = []
    for parent in checked:
        depth.append(0 if parent == -1 else depth[parent] + 1)
    levels: list[list[int]] = [[] for _ in range(max(depth, default=-1) + 1)]
    for joint, d in enumerate(depth):
        levels[d].append(joint)
    return levels


def ancestors(parents: Sequence[int], joint: int) -> list[int]:
    """Ancestors of ``joint``, nearest first (excluding the root frame, which has index -1)."""
    checked = validate_parents(parents)
    chain: list[int] = []
    parent = checked[joint]
    while parent != -1:
        chain.append(parent)
        parent = checked[parent]
    return chain


def body_joint_index(joint: int | str) -> int:
    """Index among the 23 body joints of a name (``"left_elbow"``) or an index.

    Raises:
        ValueError: an unknown name (the message lists the names).
        IndexError: an index outside 0..22.
    """
    if isinstance(joint, str):
        if joint not in BODY_JOINT_NAMES:
            raise ValueError(
                f"unknown joint {joint!r}; body joints are {', '.join(BODY_JOINT_NAMES)}"
            )
        return BODY_JOINT_NAMES.index(joint)
    if not 0 <= int(joint) < len(BODY_JOINT_NAMES):
        raise IndexError(f"joint index {joint} is outside 0..{len(BODY_JOINT_NAMES) - 1}")
    return int(joint)


def compose_global_rotations(
    relative: torch.Tensor, parents: Sequence[int], root: torch.Tensor | None = None
) -> torch.Tensor:
    """Forward kinematics of rotations: relative joint rotations to global ones.

    ``global_j = global_{parent(j)} @ relative_j``, with the root frame's rotation ``root`` for
    joints whose parent is -1. Joints at the same tree depth are composed in one batched
    product, so the loop runs over depth levels (9 for SMPL), not joints.

    Args:
        relative: ``(..., J, 3, 3)`` rotations of each joint relative to its parent.
        parents: length-J parents (-1 = attached to the root frame), parents before children.
        root: optional ``(..., 3, 3)`` root (global) rotation, broadcastable; identity if None.

    Returns:
        ``(..., J, 3, 3)`` global rotations.
    """
    parent_list = validate_parents(parents)
    if relative.shape[-3:] != (len(parent_list), 3, 3):
        raise ValueError(
            f"relative rotations must have shape (..., {len(parent_list)}, 3, 3), "
            f"got {tuple(relative.shape)}"
        )
    if root is not None:
        batch = torch.broadcast_shapes(relative.shape[:-3], root.shape[:-2])
        relative = relative.expand(*batch, *relative.shape[-3:])
        root = root.expand(*batch, 3, 3)
    global_rot = relative.clone()
    for level in depth_levels(parent_list):
        index = torch.tensor(level, device=relative.device)
        level_parents = [parent_list[j] for j in level]
        if level_parents[0] == -1:  # depth 0: children of the root frame
            if root is not None:
                global_rot[..., index, :, :] = root.unsqueeze(-3) @ relative[..., index, :, :]
            continue
        parent_index = torch.tensor(level_parents, device=relative.device)
        global_rot[..., index, :, :] = (
            global_rot[..., parent_index, :, :] @ relative[..., index, :, :]
        )
    return global_rot


def rotation_angle(first: torch.Tensor, second: torch.Tensor) -> torch.Tensor:
    """The angle of the rotation taking ``first`` to ``second``, radians in [0, pi].

    Args:
        first, second: ``(..., 3, 3)`` rotation matrices (broadcastable).

    Returns:
        ``(...)`` ``arccos((trace(first^T second) - 1) / 2)``, the cosine clipped to [-1, 1].
    """
    trace = (first.transpose(-1, -2) @ second).diagonal(dim1=-2, dim2=-1).sum(-1)
    return torch.arccos(((trace - 1) / 2).clamp(-1.0, 1.0))

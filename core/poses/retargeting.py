"""Retarget BVH motion onto the SMPL 24-joint tree through global joint orientations.

Method (per frame, per SMPL joint j with a source in the flavour's table):

1. ``G`` = the global rotation of the driving BVH joint (forward kinematics of the BVH channels;
   all BVH joint frames are parallel to the world in the BVH rest pose).
2. The two skeletons' rest poses differ (the ``max``/``asf`` rests hang the arms and splay the
   legs; SMPL's rest is a T-pose). A fixed rest alignment ``A_j`` (the smallest rotation taking
   SMPL's rest bone direction onto the BVH's rest bone direction, both in the BVH world) makes
   ``G @ A_j`` point SMPL's bone where the BVH bone points. Joints without a table bone
   (root, torso chain, SMPL leaves) reuse their parent's alignment, so the torso's is identity.
3. Change of axes into SMPL coordinates: ``D_j = C @ G @ A_j @ C^T``.
4. Relative rotation ``R_j = D_parent(j)^T @ D_j``; the pelvis's ``D`` is the global orientation.

SMPL joints without a source copy their parent's ``D`` (identity relative rotation). A BVH rest
pose whose bones already point along SMPL's rest bones therefore retargets to all identities.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import roma
import torch

from hkpd.body import BodyModel
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS
from hkpd.poses.bvh import BvhMotion
from hkpd.poses.bvh_kinematics import forward_kinematics, local_rotations
from hkpd.poses.skeleton_flavours import JointSource, SkeletonFlavour, detect_flavour

# For SMPL joints with several children, the child that ends the joint's bone.
_BONE_CHILD = {"spine3": "neck"}


@dataclass(frozen=True)
class RetargetedMotion:
    """SMPL rotations of a retargeted clip.

    Attributes:
        body_pose: ``(F, 23, 3, 3)`` float64 rotations of the 23 body joints relative to their
            parents (SMPL axes).
        global_orient: ``(F, 3, 3)`` float64 pelvis orientation in the mocap world, SMPL axes
            (Y up); identity = upright, facing +Z.
        flavour: name of the BVH skeleton flavour.
        name: clip name.
    """

    body_pose: torch.Tensor
    global_orient: torch.Tensor
    flavour: str
    name: str

    @property
    def num_frames(self) -> int:
        return int(self.body_pose.shape[0])


@cache
def smpl_rest_bone_directions() -> torch.Tensor:
    """Unit direction of each SMPL joint's bone (joint -> its child) in the mean-shape T-pose.

    Returns:
        ``(24, 3)`` float64, SMPL axes; zero rows for leaf joints (head, feet, hands).
    """
    with torch.no_grad():
        body = BodyModel().double()
        joints = body.rest_joints(torch.zeros(1, body.num_betas, dtype=torch.float64))[0]
    directions = torch.zeros(24, 3, dtype=torch.float64)
    for joint, name in enumerate(SMPL_JOINT_NAMES):
        children = [c for c, p in enumerate(SMPL_PARENTS) if p == joint]
        if name in _BONE_CHILD:
            children = [SMPL_JOINT_NAMES.index(_BONE_CHILD[name])]
        if len(children) == 1:
            bone = joints[children[0]] - joints[joint]
            directions[joint] = bone / bone.norm()
    return directions


def rotation_between(source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """The smallest rotation taking direction ``source`` onto direction ``target``.

    Args:
        source, target: ``(3,)`` non-zero vectors (need not be unit length).

    Returns:
        ``(3, 3)`` rotation matrix ``R`` with ``R @ source`` parallel to ``target``.
    """
    a = source / source.norm()
    b = target / target.norm()
    axis = torch.linalg.cross(a, b)
    sin = axis.norm()
    cos = torch.dot(a, b)
    if sin < 1e-9:
        if cos > 0:
            return torch.eye(3, dtype=a.dtype)
        # Opposite directions: half a turn about any axis perpendicular to a.
        helper = torch.eye(3, dtype=a.dtype)[int(torch.argmin(a.abs()))]
        axis = torch.linalg.cross(a, helper)
        return roma.rotvec_to_rotmat(torch.pi * axis / axis.norm())
    return roma.rotvec_to_rotmat(axis / sin * torch.atan2(sin, cos))


def rest_alignments(motion: BvhMotion, flavour: SkeletonFlavour) -> torch.Tensor:
    """The fixed rest alignment ``A_j`` of each SMPL joint (see the module docstring).

    Returns:
        ``(24, 3, 3)`` float64 rotations in BVH world axes.
    """
    skeleton = motion.skeleton
    identity = torch.eye(3, dtype=torch.float64)
    rest_rotations = identity.expand(1, skeleton.num_joints, 3, 3)
    _, rest_positions = forward_kinematics(skeleton, rest_rotations)
    rest_positions = rest_positions[0]
    axes = torch.tensor(flavour.bvh_to_smpl_axes, dtype=torch.float64)
    smpl_directions = smpl_rest_bone_directions() @ axes  # rows: C^T s, i.e. in BVH axes
    alignments = identity.repeat(24, 1, 1)
    for joint, name in enumerate(SMPL_JOINT_NAMES):
        source = flavour.sources.get(name)
        parent = SMPL_PARENTS[joint]
        if source is None or source.bone_end is None or smpl_directions[joint].norm() == 0:
            alignments[joint] = alignments[parent] if parent >= 0 else identity
            continue
        bone = rest_positions[skeleton.index(source.bone_end)]
        bone = bone - rest_positions[skeleton.index(source.driver)]
        if bone.norm() < 1e-9:
            raise ValueError(
                f"{flavour.name} flavour: BVH bone {source.driver}->{source.bone_end} has zero "
                "length in the rest pose; choose another bone_end"
            )
        alignments[joint] = rotation_between(smpl_directions[joint], bone)
    return alignments


def _driver_rotation(
    global_rotations: torch.Tensor, motion: BvhMotion, source: JointSource
) -> torch.Tensor:
    rotation = global_rotations[:, motion.skeleton.index(source.driver)]
    if source.blend_with is None or source.blend == 0.0:
        return rotation
    other = global_rotations[:, motion.skeleton.index(source.blend_with)]
    step = roma.rotmat_to_rotvec(rotation.transpose(-1, -2) @ other)
    return rotation @ roma.rotvec_to_rotmat(source.blend * step)


def retarget(motion: BvhMotion, flavour: SkeletonFlavour | None = None) -> RetargetedMotion:
    """Retarget a BVH clip onto SMPL (see the module docstring for the method).

    Args:
        motion: a parsed BVH clip.
        flavour: its skeleton flavour; detected from the joint names when ``None``.

    Returns:
        The SMPL rotations; the flavour's added first frame (cgspeed T-pose) is dropped.

    Raises:
        ValueError: unknown skeleton, or a clip with no frames left.
    """
    if flavour is None:
        flavour = detect_flavour(motion.skeleton)
    rotations = local_rotations(motion)
    if flavour.drop_first_frame:
        rotations = rotations[1:]
    if rotations.shape[0] == 0:
        raise ValueError(f"clip {motion.name!r} has no frames after dropping the T-pose frame")
    global_rotations, _ = forward_kinematics(motion.skeleton, rotations)
    alignments = rest_alignments(motion, flavour)
    axes = torch.tensor(flavour.bvh_to_smpl_axes, dtype=torch.float64)
    same_axes = bool(torch.equal(axes, torch.eye(3, dtype=torch.float64)))

    smpl_globals: list[torch.Tensor] = []
    for joint, name in enumerate(SMPL_JOINT_NAMES):
        source = flavour.sources.get(name)
        if source is None:
            smpl_globals.append(smpl_globals[SMPL_PARENTS[joint]])
            continue
        driver = _driver_rotation(global_rotations, motion, source)
        # Expanding the fixed matrix to the batch keeps torch on its fast small-matrix batched
        # path (a broadcast (F, 3, 3) @ (3, 3) goes through a general, much slower GEMM).
        rotation = driver @ alignments[joint].expand_as(driver)
        if not same_axes:
            rotation = axes.expand_as(rotation) @ rotation @ axes.T.expand_as(rotation)
        smpl_globals.append(rotation)
    body_pose = torch.stack(
        [
            smpl_globals[SMPL_PARENTS[joint]].transpose(-1, -2) @ smpl_globals[joint]
            for joint in range(1, 24)
        ],
        dim=1,
    )
    return RetargetedMotion(
        body_pose=body_pose,
        global_orient=smpl_globals[0],
        flavour=flavour.name,
        name=motion.name,
    )

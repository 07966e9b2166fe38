"""Training poses: BVH motion capture retargeted onto the SMPL 24-joint tree, pose banks, and a
procedural fallback prior (the first stage of the synthetic-data flow: poses -> bodies ->
images)."""

from hkpd.mirror_symmetry import mirror_pose
from hkpd.poses.bank import PoseBank
from hkpd.poses.bank_builder import BuildSummary, build_pose_bank
from hkpd.poses.bvh import BvhMotion, BvhParseError, BvhSkeleton, load_bvh, parse_bvh
from hkpd.poses.procedural import JOINT_LIMITS, JointLimit, ProceduralPosePrior
from hkpd.poses.retargeting import RetargetedMotion, retarget
from hkpd.poses.selection import pose_source
from hkpd.poses.skeleton_flavours import FLAVOURS, SkeletonFlavour, detect_flavour
from hkpd.poses.source import PoseSource
from hkpd.poses.subject_split import assign_splits, subject_of

__all__ = [
    "FLAVOURS",
    "JOINT_LIMITS",
    "BuildSummary",
    "BvhMotion",
    "BvhParseError",
    "BvhSkeleton",
    "JointLimit",
    "PoseBank",
    "PoseSource",
    "ProceduralPosePrior",
    "RetargetedMotion",
    "SkeletonFlavour",
    "assign_splits",
    "build_pose_bank",
    "detect_flavour",
    "load_bvh",
    "mirror_pose",
    "parse_bvh",
    "pose_source",
    "retarget",
    "subject_of",
]

"""Explicit joint-name tables from the CMU BVH skeleton flavours to the SMPL 24-joint tree.

Each table says, for every SMPL joint, which BVH joint's *global* rotation drives it
(:class:`JointSource`). SMPL joints missing from a table (fingers-level hands, Daz toes) keep the
rotation of their SMPL parent, i.e. an identity relative rotation. BVH joints missing from the
tables (CMU's hip-joint and lower-neck helper bones, eyes, fingers, thumbs) are not lost: their
rotations are part of the global rotations of the mapped joints below them.

Flavours (see ``/work/shared/data/cmu_mocap/MANIFEST.txt``):

* ``daz``: cgspeed "Daz-friendly" release, 43 joints (``hip``, ``abdomen``, ``chest``,
  ``lShldr`` ...), rest pose a T-pose, first frame an added T-pose.
* ``max``: cgspeed "3dsMax-friendly" release, 31 joints (``Hips``, ``LeftHip``, ``Chest2`` ...),
  rest pose with the arms hanging and the legs splayed, first frame dropped as in all cgspeed
  files.
* ``asf``: raw amc2bvh export with the CMU ASF bone names (``lfemur``, ``lhumerus`` ...), the same
  31-joint topology and rest pose as ``max``, no added frame.

All three use BVH world axes Y up, the rest pose facing +Z with its left side at +X, which are
SMPL's axes, so ``bvh_to_smpl_axes`` is the identity for them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from hkpd.poses.bvh import BvhSkeleton

_IDENTITY_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


@dataclass(frozen=True)
class JointSource:
    """Where one SMPL joint's global rotation comes from.

    Attributes:
        driver: BVH joint whose global rotation is used.
        bone_end: BVH joint (or end site) at the far end of the bone, used to line the BVH rest
            bone up with the SMPL rest bone; ``None`` reuses the SMPL parent's rest alignment.
            The tables use ``None`` for the root, for SMPL's leaf joints (no bone of their own)
            and for the torso chain (spine1-3, neck, head): every skeleton's zero pose has an
            upright, neutral torso, and the few degrees by which the spine bones' directions
            differ come from different spine geometry (SMPL's thoracic curve), not posture.
        blend_with: optional second BVH joint; the global rotation is then the geodesic
            interpolation ``slerp(G[driver], G[blend_with], blend)``. Used to spread one BVH
            joint's rotation over two SMPL spine joints.
        blend: interpolation weight in [0, 1].
    """

    driver: str
    bone_end: str | None
    blend_with: str | None = None
    blend: float = 0.0


@dataclass(frozen=True)
class SkeletonFlavour:
    """A BVH skeleton family and how it maps onto SMPL.

    Attributes:
        name: short id (``"daz"``, ``"max"``, ``"asf"``).
        signature: joint names whose presence identifies the flavour.
        sources: SMPL joint name -> :class:`JointSource`; must contain ``"pelvis"``.
        drop_first_frame: the first motion frame is an added calibration T-pose (cgspeed).
        bvh_to_smpl_axes: 3x3 matrix taking BVH world coordinates to SMPL coordinates.
    """

    name: str
    signature: tuple[str, ...]
    sources: Mapping[str, JointSource]
    drop_first_frame: bool
    bvh_to_smpl_axes: tuple[tuple[float, ...], ...] = field(default=_IDENTITY_AXES)


DAZ = SkeletonFlavour(
    name="daz",
    signature=("hip", "abdomen", "chest", "lShldr", "rShldr", "lThigh", "rThigh"),
    # Daz has two spine joints (abdomen, chest) where SMPL has three: spine1 follows the
    # abdomen, spine3 the chest, and spine2 sits halfway, so the chest's bend relative to the
    # abdomen is split evenly between spine2 and spine3. Daz has no toes: SMPL feet stay straight.
    sources={
        "pelvis": JointSource("hip", None),
        "left_hip": JointSource("lThigh", "lShin"),
        "right_hip": JointSource("rThigh", "rShin"),
        "spine1": JointSource("abdomen", None),
        "left_knee": JointSource("lShin", "lFoot"),
        "right_knee": JointSource("rShin", "rFoot"),
        "spine2": JointSource("abdomen", None, blend_with="chest", blend=0.5),
        "left_ankle": JointSource("lFoot", "lFoot_end"),
        "right_ankle": JointSource("rFoot", "rFoot_end"),
        "spine3": JointSource("chest", None),
        "neck": JointSource("neck", None),
        "left_collar": JointSource("lCollar", "lShldr"),
        "right_collar": JointSource("rCollar", "rShldr"),
        "head": JointSource("head", None),
        "left_shoulder": JointSource("lShldr", "lForeArm"),
        "right_shoulder": JointSource("rShldr", "rForeArm"),
        "left_elbow": JointSource("lForeArm", "lHand"),
        "right_elbow": JointSource("rForeArm", "rHand"),
        "left_wrist": JointSource("lHand", "lMid1"),
        "right_wrist": JointSource("rHand", "rMid1"),
    },
    drop_first_frame=True,
)

MAX = SkeletonFlavour(
    name="max",
    signature=("Hips", "LeftHip", "LeftKnee", "Chest2", "LeftShoulder", "RightShoulder"),
    # 'LeftWrist' is CMU's forearm-twist bone ('lwrist'); 'lhand' carries the wrist flexion and
    # its global rotation includes that twist. 'lowerneck' and 'Neck' (CMU 'upperneck') both lie
    # between SMPL's neck and head joints, so the head's relative rotation includes 'Neck'.
    sources={
        "pelvis": JointSource("Hips", None),
        "left_hip": JointSource("LeftHip", "LeftKnee"),
        "right_hip": JointSource("RightHip", "RightKnee"),
        "spine1": JointSource("lowerback", None),
        "left_knee": JointSource("LeftKnee", "LeftAnkle"),
        "right_knee": JointSource("RightKnee", "RightAnkle"),
        "spine2": JointSource("Chest", None),
        "left_ankle": JointSource("LeftAnkle", "LeftToe"),
        "right_ankle": JointSource("RightAnkle", "RightToe"),
        "spine3": JointSource("Chest2", None),
        "left_foot": JointSource("LeftToe", None),
        "right_foot": JointSource("RightToe", None),
        "neck": JointSource("lowerneck", None),
        "left_collar": JointSource("LeftCollar", "LeftShoulder"),
        "right_collar": JointSource("RightCollar", "RightShoulder"),
        "head": JointSource("Head", None),
        "left_shoulder": JointSource("LeftShoulder", "LeftElbow"),
        "right_shoulder": JointSource("RightShoulder", "RightElbow"),
        "left_elbow": JointSource("LeftElbow", "LeftWrist"),
        "right_elbow": JointSource("RightElbow", "RightWrist"),
        "left_wrist": JointSource("lhand", "LFingers"),
        "right_wrist": JointSource("rhand", "RFingers"),
    },
    drop_first_frame=True,
)

ASF = SkeletonFlavour(
    name="asf",
    signature=("hip", "lfemur", "rfemur", "thorax", "lhumerus", "rhumerus"),
    # Same topology as 'max' under CMU's own ASF bone names.
    sources={
        "pelvis": JointSource("hip", None),
        "left_hip": JointSource("lfemur", "ltibia"),
        "right_hip": JointSource("rfemur", "rtibia"),
        "spine1": JointSource("lowerback", None),
        "left_knee": JointSource("ltibia", "lfoot"),
        "right_knee": JointSource("rtibia", "rfoot"),
        "spine2": JointSource("upperback", None),
        "left_ankle": JointSource("lfoot", "ltoes"),
        "right_ankle": JointSource("rfoot", "rtoes"),
        "spine3": JointSource("thorax", None),
        "left_foot": JointSource("ltoes", None),
        "right_foot": JointSource("rtoes", None),
        "neck": JointSource("lowerneck", None),
        "left_collar": JointSource("lclavicle", "lhumerus"),
        "right_collar": JointSource("rclavicle", "rhumerus"),
        "head": JointSource("head", None),
        "left_shoulder": JointSource("lhumerus", "lradius"),
        "right_shoulder": JointSource("rhumerus", "rradius"),
        "left_elbow": JointSource("lradius", "lwrist"),
        "right_elbow": JointSource("rradius", "rwrist"),
        "left_wrist": JointSource("lhand", "lfingers"),
        "right_wrist": JointSource("rhand", "rfingers"),
    },
    drop_first_frame=False,
)

FLAVOURS: dict[str, SkeletonFlavour] = {f.name: f for f in (DAZ, MAX, ASF)}
"""The known flavours by name."""


def detect_flavour(skeleton: BvhSkeleton) -> SkeletonFlavour:
    """The flavour whose signature joints all appear in ``skeleton``.

    Raises:
        ValueError: if no known flavour matches (the message lists the skeleton's joints).
    """
    names = set(skeleton.names)
    for flavour in FLAVOURS.values():
        if all(n in names for n in flavour.signature):
            missing = [
                n
                for s in flavour.sources.values()
                for n in (s.driver, s.bone_end, s.blend_with)
                if n is not None and n not in names
            ]
            if missing:
                raise ValueError(
                    f"skeleton looks like the {flavour.name!r} flavour but lacks joints {missing}"
                )
            return flavour
    raise ValueError(
        "unknown BVH skeleton: it matches none of the flavours "
        f"{sorted(FLAVOURS)} (joints: {', '.join(n for n in skeleton.names if '_end' not in n)})"
    )

"""How Anny's 104-bone rig groups into SMPL's 24 joints.

Each SMPL joint owns a group of Anny bones that move rigidly together. Its skinning weight on a
vertex is the sum of its bones' weights there. Its location is the mean of the heads of its
*location bones*, usually the group's single root bone, so joints stay exactly linear in Anny's
mesh. The groups were chosen by comparing Anny's bone heads with SMPL's joint layout:

- the pelvis takes the root, both pelvis bones and the two lowest spine bones;
- the spine joints take spine03 / spine02 / spine01 (spine01 carries the clavicles, as SMPL's
  spine3 carries the collars);
- a collar is clavicle + shoulder01, and a shoulder is the upper arm (its head is the
  glenohumeral joint);
- a wrist joint takes the palm (wrist + metacarpals), and a hand joint the fingers, located at
  the mean of the four knuckles;
- a foot joint takes the toes, located at the mean of the five toe bases.

This module holds only the mapping and checks on it; it does not import anny.
"""

from __future__ import annotations

from collections.abc import Sequence

from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS


def _side(names: Sequence[str], side: str) -> tuple[str, ...]:
    return tuple(f"{name}.{side}" for name in names)


def _toes(side: str) -> tuple[str, ...]:
    counts = {1: 2, 2: 3, 3: 3, 4: 3, 5: 3}
    return tuple(f"toe{t}-{k}.{side}" for t, n in counts.items() for k in range(1, n + 1))


def _fingers(side: str) -> tuple[str, ...]:
    return tuple(f"finger{f}-{k}.{side}" for f in range(1, 6) for k in range(1, 4))


SMPL_BONE_GROUPS: dict[str, tuple[str, ...]] = {
    "pelvis": ("root", "pelvis.L", "pelvis.R", "spine05", "spine04"),
    "left_hip": _side(("upperleg01", "upperleg02"), "L"),
    "right_hip": _side(("upperleg01", "upperleg02"), "R"),
    "spine1": ("spine03",),
    "left_knee": _side(("lowerleg01", "lowerleg02"), "L"),
    "right_knee": _side(("lowerleg01", "lowerleg02"), "R"),
    "spine2": ("spine02",),
    "left_ankle": ("foot.L",),
    "right_ankle": ("foot.R",),
    "spine3": ("spine01",),
    "left_foot": _toes("L"),
    "right_foot": _toes("R"),
    "neck": ("neck01", "neck02", "neck03"),
    "left_collar": _side(("clavicle", "shoulder01"), "L"),
    "right_collar": _side(("clavicle", "shoulder01"), "R"),
    "head": ("head", "eye.L", "eye.R"),
    "left_shoulder": _side(("upperarm01", "upperarm02"), "L"),
    "right_shoulder": _side(("upperarm01", "upperarm02"), "R"),
    "left_elbow": _side(("lowerarm01", "lowerarm02"), "L"),
    "right_elbow": _side(("lowerarm01", "lowerarm02"), "R"),
    "left_wrist": ("wrist.L", *(f"metacarpal{k}.L" for k in range(1, 5))),
    "right_wrist": ("wrist.R", *(f"metacarpal{k}.R" for k in range(1, 5))),
    "left_hand": _fingers("L"),
    "right_hand": _fingers("R"),
}
"""Anny bone labels owned by each SMPL joint, in SMPL joint order."""

SMPL_LOCATION_BONES: dict[str, tuple[str, ...]] = {
    "left_foot": tuple(f"toe{t}-1.L" for t in range(1, 6)),
    "right_foot": tuple(f"toe{t}-1.R" for t in range(1, 6)),
    "left_hand": tuple(f"finger{f}-1.L" for f in range(2, 6)),
    "right_hand": tuple(f"finger{f}-1.R" for f in range(2, 6)),
}
"""Joints located at the mean of several bone heads; every other joint sits at its group root."""


def group_index_of_bones(bone_labels: Sequence[str]) -> list[int]:
    """SMPL joint index owning each Anny bone.

    Args:
        bone_labels: Anny's bone labels, in Anny's order (104 for the default rig).

    Returns:
        For each bone, the index (0..23) of its SMPL joint.

    Raises:
        ValueError: if a bone is in no group, in two groups, or a group names an unknown bone.
    """
    owner: dict[str, int] = {}
    for joint, name in enumerate(SMPL_JOINT_NAMES):
        for bone in SMPL_BONE_GROUPS[name]:
            if bone in owner:
                raise ValueError(f"bone {bone!r} is in two SMPL groups")
            owner[bone] = joint
    unknown = sorted(set(owner) - set(bone_labels))
    missing = [bone for bone in bone_labels if bone not in owner]
    if unknown or missing:
        raise ValueError(f"rig mismatch: unknown bones {unknown}, ungrouped bones {missing}")
    return [owner[bone] for bone in bone_labels]


def group_root_bones(bone_labels: Sequence[str], bone_parents: Sequence[int]) -> list[list[int]]:
    """For each SMPL joint, the Anny bones of its group whose parent lies outside the group.

    Also checks that each such parent belongs to the SMPL parent joint's group, so the grouped
    rig really is SMPL's tree.

    Returns:
        ``roots[j]`` lists bone indices (e.g. one for the knee, five for the toes).
    """
    owner = group_index_of_bones(bone_labels)
    roots: list[list[int]] = [[] for _ in SMPL_JOINT_NAMES]
    for bone, parent in enumerate(bone_parents):
        joint = owner[bone]
        if parent >= 0 and owner[parent] == joint:
            continue
        expected_parent = SMPL_PARENTS[joint]
        actual_parent = owner[parent] if parent >= 0 else -1
        if actual_parent != expected_parent:
            names = ("nothing", *SMPL_JOINT_NAMES)  # index -1 + 1 -> "nothing"
            raise ValueError(
                f"bone {bone_labels[bone]!r} of {SMPL_JOINT_NAMES[joint]} hangs from "
                f"{names[actual_parent + 1]}, expected {names[expected_parent + 1]}"
            )
        roots[joint].append(bone)
    return roots


def location_bones(bone_labels: Sequence[str], bone_parents: Sequence[int]) -> list[list[int]]:
    """For each SMPL joint, the Anny bones whose heads' mean is the joint location."""
    roots = group_root_bones(bone_labels, bone_parents)
    result = []
    for joint, name in enumerate(SMPL_JOINT_NAMES):
        if name in SMPL_LOCATION_BONES:
            result.append([bone_labels.index(bone) for bone in SMPL_LOCATION_BONES[name]])
        elif len(roots[joint]) == 1:
            result.append(roots[joint])
        else:
            raise ValueError(f"{name} has several root bones; list its location bones")
    return result

"""Retargeting BVH motion onto SMPL: rest poses, a known elbow bend, rest alignment, flavours."""

from __future__ import annotations

from pathlib import Path

import pytest
import roma
import torch
from test_poses_bvh import max_flavour_motion, max_flavour_skeleton

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses.bvh import BvhMotion, load_bvh
from hkpd.poses.bvh_kinematics import axis_rotation
from hkpd.poses.retargeting import retarget, rotation_between
from hkpd.poses.skeleton_flavours import FLAVOURS, MAX, detect_flavour

CMU = Path("/work/shared/data/cmu_mocap")
IDENTITY = torch.eye(3, dtype=torch.float64)


def degrees(value: float) -> torch.Tensor:
    return torch.tensor(value, dtype=torch.float64)


def test_rest_pose_retargets_to_identity() -> None:
    skeleton = max_flavour_skeleton()
    # Frame 0 is the cgspeed T-pose frame that gets dropped; frame 1 is the rest pose.
    motion = max_flavour_motion(skeleton, [{"LeftElbow": {"Yrotation": 50.0}}, {}])
    clip = retarget(motion)
    assert clip.flavour == "max" and clip.num_frames == 1
    torch.testing.assert_close(clip.body_pose[0], IDENTITY.expand(23, 3, 3), atol=1e-6, rtol=0)
    torch.testing.assert_close(clip.global_orient[0], IDENTITY, atol=1e-9, rtol=0)


def test_known_elbow_bend_and_root_turn() -> None:
    skeleton = max_flavour_skeleton()
    frame = {"LeftElbow": {"Yrotation": -90.0}, "Hips": {"Yrotation": 30.0, "Xposition": 5.0}}
    clip = retarget(max_flavour_motion(skeleton, [{}, frame]))
    elbow = BODY_JOINT_NAMES.index("left_elbow")
    expected = axis_rotation("Y", degrees(-90.0))
    torch.testing.assert_close(clip.body_pose[0, elbow], expected, atol=1e-6, rtol=0)
    others = [j for j in range(23) if j != elbow]
    torch.testing.assert_close(
        clip.body_pose[0, others], IDENTITY.expand(22, 3, 3), atol=1e-6, rtol=0
    )
    torch.testing.assert_close(clip.global_orient[0], axis_rotation("Y", degrees(30.0)))
    # The bend folds the left forearm forwards (+Z): the SMPL forearm bone (+X) maps to +Z.
    forearm = clip.body_pose[0, elbow] @ torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(forearm, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))


def test_rest_alignment_maps_hanging_arms_to_smpl_t_pose() -> None:
    skeleton = max_flavour_skeleton(arms_down=True)
    # Raising both hanging arms sideways to horizontal is SMPL's T-pose; the rest (arms down)
    # becomes a 90 degree shoulder rotation about the forward axis.
    raised = {"LeftShoulder": {"Zrotation": 90.0}, "RightShoulder": {"Zrotation": -90.0}}
    clip = retarget(max_flavour_motion(skeleton, [{}, raised, {}]))
    torch.testing.assert_close(clip.body_pose[0], IDENTITY.expand(23, 3, 3), atol=1e-6, rtol=0)
    left = BODY_JOINT_NAMES.index("left_shoulder")
    right = BODY_JOINT_NAMES.index("right_shoulder")
    torch.testing.assert_close(clip.body_pose[1, left], axis_rotation("Z", degrees(-90.0)))
    torch.testing.assert_close(clip.body_pose[1, right], axis_rotation("Z", degrees(90.0)))


def test_rotation_between_directions() -> None:
    generator = torch.Generator().manual_seed(0)
    for _ in range(5):
        a, b = torch.randn(2, 3, generator=generator, dtype=torch.float64)
        rotation = rotation_between(a, b)
        torch.testing.assert_close(rotation @ (a / a.norm()), b / b.norm())
    a = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(rotation_between(a, -a) @ a, -a)
    torch.testing.assert_close(rotation_between(a, 3 * a), IDENTITY)


def test_unknown_skeleton_is_rejected_with_joint_list() -> None:
    skeleton = max_flavour_skeleton()
    renamed = type(skeleton)(
        tuple(n.replace("Chest2", "UpperChest") for n in skeleton.names),
        skeleton.parents,
        skeleton.offsets,
        skeleton.channels,
        skeleton.is_end_site,
    )
    with pytest.raises(ValueError, match=r"unknown BVH skeleton.*UpperChest"):
        detect_flavour(renamed)
    assert detect_flavour(skeleton) is MAX


def test_flavour_tables_cover_every_smpl_limb() -> None:
    limbs = ("hip", "knee", "ankle", "collar", "shoulder", "elbow", "wrist")
    required = {"pelvis", "spine1", "spine2", "spine3", "neck", "head"}
    required |= {f"{side}_{limb}" for side in ("left", "right") for limb in limbs}
    for flavour in FLAVOURS.values():
        assert required <= set(flavour.sources), flavour.name
        for name, source in flavour.sources.items():
            if name.startswith("left_"):
                mirrored = flavour.sources["right_" + name[5:]]
                assert mirrored.driver != source.driver, (flavour.name, name)


@pytest.mark.skipif(not CMU.is_dir(), reason="CMU mocap data not available")
@pytest.mark.parametrize(
    "relative",
    [
        "daz_bvh_Przestr/02_01.bvh",
        "max_bvh_walk_shannonkao/26_01.bvh",
        "asf_named_bvh_Przestr_16/16_01.bvh",
    ],
)
def test_real_walks_and_jumps_bend_knees_backwards_and_stay_upright(relative: str) -> None:
    motion: BvhMotion = load_bvh(CMU / relative)
    clip = retarget(motion)
    assert clip.flavour in FLAVOURS
    knees = [BODY_JOINT_NAMES.index("left_knee"), BODY_JOINT_NAMES.index("right_knee")]
    rotvec = roma.rotmat_to_rotvec(clip.body_pose[:, knees])
    bent = rotvec.norm(dim=-1) > torch.deg2rad(degrees(20.0))
    # Knee flexion is about +X in SMPL (shin backwards): nearly all strongly bent knees agree.
    assert bent.float().mean() > 0.1
    assert (rotvec[..., 0][bent] > 0).float().mean() > 0.95
    # The body stays upright: the pelvis's up axis is within 35 degrees of world up.
    up = clip.global_orient[:, :, 1]
    assert (up[:, 1] > torch.cos(torch.deg2rad(degrees(35.0)))).all()

"""BVH parsing, writing and forward kinematics; also builds the synthetic clips that the other
pose tests use."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.kinematic_tree import SMPL_JOINT_NAMES
from hkpd.poses.bvh import BvhMotion, BvhParseError, BvhSkeleton, parse_bvh
from hkpd.poses.bvh_kinematics import axis_rotation, forward_kinematics, local_rotations
from hkpd.poses.bvh_writer import format_bvh

SMALL_BVH = (
    "HIERARCHY\r\n"
    "ROOT hip\r\n{\r\n  OFFSET 0 0 0\r\n"
    "  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\r\n"
    "  JOINT a\r\n  {\r\n    OFFSET 0 1 0\r\n    CHANNELS 3 Zrotation Xrotation Yrotation\r\n"
    "    End Site\r\n    {\r\n      OFFSET 1 0 0\r\n    }\r\n  }\r\n"
    "  JOINT b\r\n  {\r\n    OFFSET 0 -1 0\r\n    CHANNELS 3 Zrotation Yrotation Xrotation\r\n"
    "    End Site\r\n    {\r\n      OFFSET 1 0 0\r\n    }\r\n  }\r\n}\r\n"
    "MOTION\r\nFrames:\t2\r\nFrame Time:\t0.0083333\r\n"
    "1 2 3 0 0 0 0 0 0 0 0 0\r\n"
    "1 2 3 90 0 0 90 90 0 90 90 0\r\n"
)


# --- synthetic clips shaped like SMPL, in the CMU "max" skeleton flavour -------------------------

_MAX_ARM_CHAIN = ("Collar", "Shoulder", "Elbow", "Wrist")
_ARM_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
_OTHER_CHANNELS = ("Zrotation", "Yrotation", "Xrotation")
_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")


def smpl_rest_joints() -> dict[str, np.ndarray]:
    """SMPL mean-shape rest joint positions by name (metres)."""
    with torch.no_grad():
        body = BodyModel().double()
        joints = body.rest_joints(torch.zeros(1, body.num_betas, dtype=torch.float64))[0]
    return {name: joints[i].numpy() for i, name in enumerate(SMPL_JOINT_NAMES)}


def max_flavour_skeleton(arms_down: bool = False) -> BvhSkeleton:
    """A 'max'-flavour BVH skeleton whose rest bones point exactly along SMPL's rest bones
    (or, with ``arms_down``, with the arms hanging straight down instead of the T-pose)."""
    smpl = smpl_rest_joints()
    up = np.array([0.0, 0.05, 0.0])
    neck_bone = smpl["head"] - smpl["neck"]
    joints: list[tuple[str, str | None, np.ndarray]] = [
        ("Hips", None, smpl["pelvis"]),
        ("lowerback", "Hips", smpl["spine1"]),
        ("Chest", "lowerback", smpl["spine2"]),
        ("Chest2", "Chest", smpl["spine3"]),
        ("lowerneck", "Chest2", smpl["neck"] - neck_bone),
        ("Neck", "lowerneck", smpl["neck"]),
        ("Head", "Neck", smpl["head"]),
        ("Head_end", "Head", smpl["head"] + up),
    ]
    for side, smpl_side in (("Left", "left"), ("Right", "right")):
        letter = side[0]
        hip = f"{letter}HipJoint"
        joints += [
            (hip, "Hips", smpl["pelvis"]),
            (f"{side}Hip", hip, smpl[f"{smpl_side}_hip"]),
            (f"{side}Knee", f"{side}Hip", smpl[f"{smpl_side}_knee"]),
            (f"{side}Ankle", f"{side}Knee", smpl[f"{smpl_side}_ankle"]),
            (f"{side}Toe", f"{side}Ankle", smpl[f"{smpl_side}_foot"]),
            (f"{side}Toe_end", f"{side}Toe", smpl[f"{smpl_side}_foot"] + [0, 0, 0.05]),
        ]
        shoulder = smpl[f"{smpl_side}_shoulder"]
        arm = [smpl[f"{smpl_side}_{n}"] for n in ("elbow", "wrist", "hand")]
        if arms_down:
            lengths = np.cumsum(
                [np.linalg.norm(b - a) for a, b in zip([shoulder, *arm], arm, strict=False)]
            )
            arm = [shoulder - np.array([0.0, length, 0.0]) for length in lengths]
        joints += [
            (f"{side}Collar", "Chest2", smpl[f"{smpl_side}_collar"]),
            (f"{side}Shoulder", f"{side}Collar", shoulder),
            (f"{side}Elbow", f"{side}Shoulder", arm[0]),
            (f"{side}Wrist", f"{side}Elbow", arm[1]),
            (f"{letter.lower()}hand", f"{side}Wrist", arm[1]),
            (f"{letter}Fingers", f"{letter.lower()}hand", arm[2]),
            (f"{letter}Fingers_end", f"{letter}Fingers", arm[2]),  # moved below
        ]
    # Depth-first order (as a BVH file lists joints), children in the order given.
    ordered: list[tuple[str, str | None, np.ndarray]] = []

    def visit(parent: str | None) -> None:
        for joint in joints:
            if joint[1] == parent:
                ordered.append(joint)
                visit(joint[0])

    visit(None)
    joints = ordered
    # Give the finger end sites some length along the hand.
    names = [j[0] for j in joints]
    positions = {name: np.asarray(position, dtype=np.float64) for name, _, position in joints}
    for letter in "LR":
        hand = positions[f"{letter}Fingers"] - positions[f"{letter.lower()}hand"]
        positions[f"{letter}Fingers_end"] = positions[f"{letter}Fingers"] + 0.3 * hand
    parents = tuple(-1 if p is None else names.index(p) for _, p, _ in joints)
    offsets = np.stack(
        [
            positions[n] - (positions[names[p]] if p >= 0 else 0)
            for n, p in zip(names, parents, strict=True)
        ]
    )
    is_end = np.array([n.endswith("_end") for n in names])
    channels = tuple(
        ()
        if end
        else _ROOT_CHANNELS
        if p < 0
        else _ARM_CHANNELS
        if any(k in n for k in _MAX_ARM_CHAIN[1:]) or n in ("lhand", "rhand")
        else _OTHER_CHANNELS
        for n, p, end in zip(names, parents, is_end, strict=True)
    )
    return BvhSkeleton(tuple(names), parents, 100.0 * offsets, channels, is_end)


def max_flavour_motion(
    skeleton: BvhSkeleton, settings: list[dict[str, dict[str, float]]], name: str = "01_01"
) -> BvhMotion:
    """A clip of ``skeleton``; ``settings[f][joint][channel] = value`` (others zero)."""
    frames = np.zeros((len(settings), skeleton.num_channels))
    columns: dict[tuple[str, str], int] = {}
    for joint, channels in zip(skeleton.names, skeleton.channels, strict=True):
        for channel in channels:
            columns[(joint, channel)] = len(columns)
    for f, frame in enumerate(settings):
        for joint, values in frame.items():
            for channel, value in values.items():
                frames[f, columns[(joint, channel)]] = value
    return BvhMotion(skeleton, frames, 1 / 120, name)


# --- tests ---------------------------------------------------------------------------------------


def test_parse_small_bvh_with_crlf_end_sites_and_both_channel_orders() -> None:
    motion = parse_bvh(SMALL_BVH, name="small")
    skeleton = motion.skeleton
    assert skeleton.names == ("hip", "a", "a_end", "b", "b_end")
    assert skeleton.parents == (-1, 0, 1, 0, 3)
    assert skeleton.is_end_site.tolist() == [False, False, True, False, True]
    np.testing.assert_allclose(skeleton.offsets[3], [0, -1, 0])
    assert skeleton.channels[1] == ("Zrotation", "Xrotation", "Yrotation")
    assert skeleton.channels[3] == ("Zrotation", "Yrotation", "Xrotation")
    assert motion.frames.shape == (2, 12) and motion.frame_time == pytest.approx(0.0083333)

    rotations = local_rotations(motion)
    z90, x90, y90 = (axis_rotation(a, torch.tensor(90.0, dtype=torch.float64)) for a in "ZXY")
    # Same numbers, different channel orders -> different matrices, each the ordered product.
    torch.testing.assert_close(rotations[1, 1], z90 @ x90)
    torch.testing.assert_close(rotations[1, 3], z90 @ y90)
    assert not torch.allclose(rotations[1, 1], rotations[1, 3])


def test_forward_kinematics_of_a_known_rotation() -> None:
    motion = parse_bvh(SMALL_BVH.replace("\r\n", "\n"))
    from hkpd.poses.bvh_kinematics import joint_translations

    rotations = local_rotations(motion)
    global_rotations, positions = forward_kinematics(
        motion.skeleton, rotations, joint_translations(motion)
    )
    # Frame 0: rest, root at (1, 2, 3).
    expected = [[1, 2, 3], [1, 3, 3], [2, 3, 3], [1, 1, 3], [2, 1, 3]]
    np.testing.assert_allclose(positions[0].numpy(), expected, atol=1e-12)
    # Frame 1: root turned 90 deg about Z: joint a (offset +Y) goes to -X of the root.
    np.testing.assert_allclose(positions[1, 1].numpy(), [0, 2, 3], atol=1e-9)
    # a's end: root Rz(90) then a's Rz(90) Rx(90): offset (1,0,0) -> Rz(180) (1,0,0) = (-1,0,0).
    np.testing.assert_allclose(positions[1, 2].numpy(), [-1, 2, 3], atol=1e-9)
    torch.testing.assert_close(global_rotations[1, 2], global_rotations[1, 1])


def test_writer_round_trip() -> None:
    skeleton = max_flavour_skeleton()
    generator = np.random.default_rng(0)
    motion = BvhMotion(skeleton, generator.uniform(-30, 30, (3, skeleton.num_channels)), 0.01)
    again = parse_bvh(format_bvh(motion, line_ending="\r\n"))
    assert again.skeleton.names == skeleton.names
    assert again.skeleton.parents == skeleton.parents
    assert again.skeleton.channels == skeleton.channels
    np.testing.assert_allclose(again.skeleton.offsets, skeleton.offsets, atol=1e-6)
    np.testing.assert_allclose(again.frames, motion.frames, atol=1e-6)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("nothing", "no MOTION"),
        (
            "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Wrotation\n}\nMOTION\n",
            "unknown channel",
        ),
        (SMALL_BVH.replace("Frames:\t2", "Frames:\t3"), "were declared"),
        (SMALL_BVH.replace("1 2 3 0", "1 x 3 0"), "non-numeric"),
        (SMALL_BVH.replace("  }\r\n}\r\nMOTION", "  }\r\nMOTION"), "unclosed"),
    ],
)
def test_bad_bvh_gives_clear_errors(text: str, message: str) -> None:
    with pytest.raises(BvhParseError, match=message):
        parse_bvh(text)

"""Left/right mirroring, near-duplicate frame removal and the subject split."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.kinematic_tree import BODY_JOINT_NAMES, SMPL_JOINT_NAMES
from hkpd.mirror_symmetry import mirror_pose
from hkpd.poses.frame_selection import select_distinct_frames
from hkpd.poses.subject_split import assign_splits, subject_of


def random_pose(count: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    generator = torch.Generator().manual_seed(seed)
    body = roma.rotvec_to_rotmat(0.5 * torch.randn(count, 23, 3, generator=generator))
    orient = roma.rotvec_to_rotmat(0.5 * torch.randn(count, 3, generator=generator))
    return body.double(), orient.double()


def test_mirroring_twice_is_identity_and_swaps_sides() -> None:
    body, orient = random_pose(4, 0)
    mirrored_body, mirrored_orient = mirror_pose(body, orient)
    again_body, again_orient = mirror_pose(mirrored_body, mirrored_orient)
    torch.testing.assert_close(again_body, body)
    torch.testing.assert_close(again_orient, orient)
    left, right = BODY_JOINT_NAMES.index("left_elbow"), BODY_JOINT_NAMES.index("right_elbow")
    reflection = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64))
    torch.testing.assert_close(mirrored_body[:, right], reflection @ body[:, left] @ reflection)
    spine = BODY_JOINT_NAMES.index("spine2")
    torch.testing.assert_close(mirrored_body[:, spine], reflection @ body[:, spine] @ reflection)
    # Still proper rotations.
    torch.testing.assert_close(
        torch.linalg.det(mirrored_body), torch.ones(4, 23, dtype=torch.float64)
    )


def test_mirrored_pose_gives_mirrored_joint_positions() -> None:
    body_model = BodyModel().double()
    body, orient = random_pose(2, 1)
    betas = torch.zeros(2, body_model.num_betas, dtype=torch.float64)
    joints = body_model(betas, body, orient).joints
    mirrored = body_model(betas, *mirror_pose(body, orient)).joints
    other_side = {"left": "right", "right": "left"}
    swap = [
        SMPL_JOINT_NAMES.index("_".join(other_side.get(p, p) for p in n.split("_")))
        for n in SMPL_JOINT_NAMES
    ]
    assert swap[SMPL_JOINT_NAMES.index("left_wrist")] == SMPL_JOINT_NAMES.index("right_wrist")
    expected = joints[:, swap] * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
    # The body's rest skeleton is left/right symmetric to ~4e-5 m.
    torch.testing.assert_close(mirrored, expected, atol=5e-4, rtol=0)


def test_select_distinct_frames_thresholds_joint_change() -> None:
    angles = torch.tensor([0.0, 1.0, 2.0, 6.0, 6.5, 20.0, 20.0, 24.0], dtype=torch.float64)
    rotvec = torch.zeros(len(angles), 23, 3, dtype=torch.float64)
    rotvec[:, 7, 0] = torch.deg2rad(angles)
    kept = select_distinct_frames(roma.rotvec_to_rotmat(rotvec), min_change_deg=5.0)
    assert kept.tolist() == [0, 3, 5]
    assert select_distinct_frames(roma.rotvec_to_rotmat(rotvec), 0.0).tolist() == list(range(8))


def test_subject_of_clip_names() -> None:
    assert subject_of("02_01") == 2
    assert subject_of("131_03") == 131
    assert subject_of("60_01_scaled") == 60
    with pytest.raises(ValueError, match="subject"):
        subject_of("walk")


def test_subject_split_is_deterministic_and_never_leaks() -> None:
    subjects = list(range(1, 41))
    splits = assign_splits(subjects, val_fraction=0.1, test_fraction=0.15)
    again = assign_splits(list(reversed(subjects)) + subjects[:5], 0.1, 0.15)
    assert splits == again
    assert set(splits) == set(subjects)  # each subject in exactly one split
    counts = {name: sum(v == name for v in splits.values()) for name in ("train", "val", "test")}
    assert counts == {"train": 30, "val": 4, "test": 6}
    assert assign_splits(subjects, 0.1, 0.15, seed=1) != splits
    assert set(assign_splits([5, 6], 0.1, 0.1).values()) == {"train"}
    with pytest.raises(ValueError):
        assign_splits(subjects, 0.6, 0.5)

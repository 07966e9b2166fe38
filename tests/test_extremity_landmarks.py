"""The hand and foot landmarks on the shipped body: where they sit, and that they move with
the wrist and ankle."""

from __future__ import annotations

import math

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import (
    EXTREMITY_MIRROR,
    LANDMARK_NAMES,
    extremity_landmarks,
)
from hkpd.mirror_symmetry import BODY_MIRROR_PERMUTATION, reflect_rotations


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel().double()


@pytest.fixture(scope="module")
def rest(body: BodyModel) -> dict[str, torch.Tensor]:
    points = extremity_landmarks(body).of_mesh(body.v_template)
    return dict(zip(LANDMARK_NAMES, points, strict=False))  # the heels are listed twice


def joint(body: BodyModel, name: str) -> torch.Tensor:
    return body.joint_template[body.joint_names.index(name)]


def test_regressor_rows_are_averages_of_few_vertices(body: BodyModel) -> None:
    landmarks = extremity_landmarks(body)
    assert landmarks.weights.shape == (len(LANDMARK_NAMES), landmarks.vertex_indices.numel())
    ones = torch.ones(len(LANDMARK_NAMES), dtype=torch.float64)
    assert torch.allclose(landmarks.weights.sum(1), ones)
    assert landmarks.vertex_indices.numel() < 1000  # a few hundred vertices, not the mesh
    assert extremity_landmarks(body) is landmarks  # chosen once per model


@pytest.mark.parametrize("side,sign", [("left", 1.0), ("right", -1.0)])
def test_foot_points_heel_low_back_toes_front(body, rest, side: str, sign: float) -> None:
    ankle, foot = joint(body, f"{side}_ankle"), joint(body, f"{side}_foot")
    heel, tip = rest[f"{side}_heel"], rest[f"{side}_foot_index"]
    big, small = rest[f"{side}_big_toe"], rest[f"{side}_small_toe"]
    # heel: behind and below the ankle; toes: in front of the foot joint, on the sole's level
    assert heel[2] < ankle[2] - 0.03 and heel[1] < ankle[1] - 0.03
    for toe in (tip, big, small):
        assert toe[2] > foot[2] + 0.03
        assert abs(float(toe[1] - heel[1])) < 0.03
    # the big toe is medial (nearer the midline) and in front of the small toe
    assert sign * big[0] < sign * small[0] - 0.03
    assert big[2] > small[2]
    # every foot point is on the foot (within a shoe's length of the ankle)
    for point in (heel, tip, big, small):
        assert torch.linalg.norm(point - ankle) < 0.3


@pytest.mark.parametrize("side,sign", [("left", 1.0), ("right", -1.0)])
def test_hand_points_beyond_the_wrist(body, rest, side: str, sign: float) -> None:
    wrist = joint(body, f"{side}_wrist")
    pinky, index, thumb = (rest[f"{side}_{name}"] for name in ("pinky", "index", "thumb"))
    for point in (pinky, index, thumb):
        assert sign * (point[0] - wrist[0]) > 0.05  # out along the arm, past the wrist
        assert torch.linalg.norm(point - wrist) < 0.2
    # palms down, thumbs forward: pinky at the back, index in front, thumb frontmost
    assert pinky[2] < wrist[2] < index[2] < thumb[2]
    assert index[2] - pinky[2] > 0.05  # across the knuckles: a hand's width apart


def test_sides_mirror_each_other(rest) -> None:
    flip = torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
    names = LANDMARK_NAMES[: len(EXTREMITY_MIRROR)]
    for name, other in zip(names, EXTREMITY_MIRROR, strict=True):
        assert torch.allclose(rest[name] * flip, rest[names[other]], atol=0.01)


def test_landmarks_follow_wrist_and_ankle_rotations(body: BodyModel) -> None:
    landmarks = extremity_landmarks(body)
    pose = torch.eye(3, dtype=torch.float64).expand(1, 23, 3, 3).clone()
    turn = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.0, math.pi / 3], dtype=torch.float64))
    pose[0, body.joint_names.index("left_wrist") - 1] = turn
    pose[0, body.joint_names.index("right_ankle") - 1] = turn
    betas = torch.zeros(1, body.num_betas, dtype=torch.float64)
    rest_pose = torch.eye(3, dtype=torch.float64).expand(1, 23, 3, 3)
    still = landmarks.of_mesh(body(betas, rest_pose).vertices)
    moved = landmarks.of_mesh(body(betas, pose).vertices)
    shift = torch.linalg.norm(moved - still, dim=-1)[0]
    shifted = {name for name, value in zip(LANDMARK_NAMES, shift, strict=True) if value > 0.02}
    assert shifted == {
        "left_pinky", "left_index", "left_thumb",
        "right_heel", "right_foot_index", "right_big_toe", "right_small_toe",
    }  # fmt: skip


def test_rows_selects_by_name(body: BodyModel) -> None:
    landmarks = extremity_landmarks(body)
    feet = landmarks.rows(("left_heel", "right_heel"))
    assert feet.weights.shape[0] == 2
    with pytest.raises(ValueError, match="unknown landmark names"):
        landmarks.rows(("left_elbow",))


def test_mirror_order_matches_the_mirrored_body(body: BodyModel) -> None:
    """The mirror image of a posed body (left and right joints swapped and reflected, as the
    mirror reading does) has the landmarks x-negated and swapped by EXTREMITY_MIRROR."""
    landmarks = extremity_landmarks(body)
    generator = torch.Generator().manual_seed(0)
    rotvecs = 0.4 * torch.randn(1, 23, 3, generator=generator, dtype=torch.float64)
    pose = roma.rotvec_to_rotmat(rotvecs)
    mirrored_pose = reflect_rotations(pose[:, list(BODY_MIRROR_PERMUTATION)])
    betas = torch.zeros(1, body.num_betas, dtype=torch.float64)
    points = landmarks.of_mesh(body(betas, pose).vertices)[0, : len(EXTREMITY_MIRROR)]
    mirrored = landmarks.of_mesh(body(betas, mirrored_pose).vertices)[0, : len(EXTREMITY_MIRROR)]
    flip = torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
    torch.testing.assert_close(mirrored, points[list(EXTREMITY_MIRROR)] * flip, atol=0.012, rtol=0)

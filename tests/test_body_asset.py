"""The shipped body model (assets/body/hkpd_body.npz) against the properties it must have."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import roma
import torch
from scipy.spatial import cKDTree

from hkpd.body import BodyModel
from hkpd.kinematic_tree import SMPL_JOINT_NAMES, SMPL_PARENTS

REFERENCE = Path(__file__).parent / "data" / "body_reference.npz"


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel().double()


def mirror_joint(name: str) -> str:
    if name.startswith("left_"):
        return "right_" + name[5:]
    if name.startswith("right_"):
        return "left_" + name[6:]
    return name


def test_shipped_model_has_smpl_structure(body: BodyModel) -> None:
    assert body.num_betas == 10 and body.num_vertices == 13492
    assert tuple(body.joint_names) == SMPL_JOINT_NAMES and tuple(body.parents) == SMPL_PARENTS
    assert body.faces.shape[1] == 3 and int(body.faces.max()) == body.num_vertices - 1
    assert body.part_labels.shape == (body.num_vertices,) and int(body.part_labels.max()) == 23


def test_zero_pose_and_shape_give_the_template(body: BodyModel) -> None:
    zero = torch.zeros(1, 10, dtype=torch.float64)
    pose = torch.eye(3, dtype=torch.float64).expand(1, 23, 3, 3)
    output = body(zero, pose)
    assert torch.allclose(output.vertices[0], body.tpose(zero)[0], atol=1e-12)
    assert torch.allclose(output.joints[0], body.rest_joints(zero)[0], atol=1e-12)


def test_t_pose_axes_and_proportions(body: BodyModel) -> None:
    joints = body.rest_joints(torch.zeros(1, 10, dtype=torch.float64))[0]
    index = {name: i for i, name in enumerate(SMPL_JOINT_NAMES)}
    # Y up: head above pelvis above ankles; the body's left is +X; arms horizontal (T-pose).
    assert joints[index["head"], 1] > joints[index["pelvis"], 1] > joints[index["left_ankle"], 1]
    assert joints[index["left_wrist"], 0] > 0.5 > -0.5 > joints[index["right_wrist"], 0]
    arm = joints[index["left_wrist"]] - joints[index["left_shoulder"]]
    assert abs(float(arm[1])) < 1e-3 and abs(float(arm[2])) < 1e-3
    # Facing +Z: the nose keypoint is in front of the head joint.
    keypoints = (
        body.keypoint_regressor.double() @ body.tpose(torch.zeros(1, 10, dtype=torch.float64))[0]
    )
    assert keypoints[0, 2] > joints[index["head"], 2] + 0.05
    height = body.tpose(torch.zeros(1, 10, dtype=torch.float64))[0, :, 1]
    assert 1.55 < float(height.max() - height.min()) < 1.85


def test_joint_regression_is_exact_against_the_builder_reference(body: BodyModel) -> None:
    reference = np.load(REFERENCE)
    betas = torch.from_numpy(reference["betas"]).double()
    joints = body.rest_joints(betas)
    vertices = body.tpose(betas)[:, torch.from_numpy(reference["vertex_indices"]).long()]
    assert torch.allclose(joints, torch.from_numpy(reference["rest_joints"]).double(), atol=2e-6)
    assert torch.allclose(
        vertices, torch.from_numpy(reference["rest_vertices"]).double(), atol=2e-6
    )


def test_template_and_weights_are_left_right_symmetric(body: BodyModel) -> None:
    template = body.tpose(torch.zeros(1, 10, dtype=torch.float64))[0].numpy()
    mirrored = template * np.array([-1.0, 1.0, 1.0])
    distance, mirror = cKDTree(template).query(mirrored)
    assert distance.max() < 2e-4  # metres
    weights = body.skinning_weights.double().numpy()
    joint_mirror = [SMPL_JOINT_NAMES.index(mirror_joint(n)) for n in SMPL_JOINT_NAMES]
    assert np.abs(weights[mirror][:, joint_mirror] - weights).max() < 1e-4


def test_first_beta_tracks_height_monotonically(body: BodyModel) -> None:
    values = torch.linspace(-3, 3, 13, dtype=torch.float64)
    betas = torch.zeros(13, 10, dtype=torch.float64)
    betas[:, 0] = values
    heights = body.tpose(betas)[..., 1]
    stature = heights.max(1).values - heights.min(1).values
    assert (stature.diff() > 0).all()
    assert float(stature[-1] - stature[0]) > 0.15  # +-3 std spans more than 15 cm


def test_rotating_a_joint_moves_only_its_skinned_subtree(body: BodyModel) -> None:
    elbow = SMPL_JOINT_NAMES.index("left_elbow")
    subtree = {elbow}
    for joint, parent in enumerate(SMPL_PARENTS):
        if parent in subtree:
            subtree.add(joint)
    pose = torch.eye(3, dtype=torch.float64).repeat(1, 23, 1, 1)
    pose[0, elbow - 1] = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.0, 1.2], dtype=torch.float64))
    zero = torch.zeros(1, 10, dtype=torch.float64)
    moved = (body(zero, pose).vertices[0] - body.tpose(zero)[0]).norm(dim=-1) > 1e-9
    influenced = body.skinning_weights[:, sorted(subtree)].sum(1) > 0
    assert moved.any() and not (moved & ~influenced).any()


def test_part_labels_cover_all_24_parts(body: BodyModel) -> None:
    counts = torch.bincount(body.part_labels.long(), minlength=24)
    assert (counts > 20).all()

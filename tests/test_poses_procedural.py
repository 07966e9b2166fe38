"""The procedural pose prior: limits, bending directions, determinism, the PoseSource protocol."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses import JOINT_LIMITS, PoseSource, ProceduralPosePrior


def test_samples_respect_every_joint_limit() -> None:
    prior = ProceduralPosePrior()
    body_pose, global_orient = prior.sample(2000, torch.Generator().manual_seed(0))
    assert body_pose.shape == (2000, 23, 3, 3) and global_orient.shape == (2000, 3, 3)
    assert body_pose.dtype == torch.float32
    for joint, name in enumerate(BODY_JOINT_NAMES):
        limit = JOINT_LIMITS[name]
        angles = roma.rotmat_to_euler(limit.order, body_pose[:, joint].double(), degrees=True)
        low = torch.tensor([r[0] for r in limit.ranges], dtype=torch.float64)
        high = torch.tensor([r[1] for r in limit.ranges], dtype=torch.float64)
        assert (angles >= low - 1e-3).all() and (angles <= high + 1e-3).all(), name
        # The samples reach well into the range, not only the neutral stance.
        spread = angles.amax(0) - angles.amin(0)
        assert (spread >= 0.5 * (high - low)).all(), name


def test_knees_and_elbows_bend_one_way() -> None:
    body_pose, _ = ProceduralPosePrior().sample(500, torch.Generator().manual_seed(1))
    down = torch.tensor([0.0, -1.0, 0.0])
    for knee in ("left_knee", "right_knee"):
        shin = body_pose[:, BODY_JOINT_NAMES.index(knee)] @ down
        assert (shin[:, 2] <= 1e-3 + 0.1 * shin[:, 1].abs()).all()  # never forwards
    for elbow, arm in (("left_elbow", 1.0), ("right_elbow", -1.0)):
        forearm = body_pose[:, BODY_JOINT_NAMES.index(elbow)] @ torch.tensor([arm, 0.0, 0.0])
        # Folding goes forwards (+Z) up to the small twist-induced wobble.
        assert (forearm[:, 2] >= -0.1).all()
        assert (forearm[:, 2] > 0.5).any()


def test_global_orientation_is_upright_with_random_heading() -> None:
    prior = ProceduralPosePrior(max_tilt_deg=15.0)
    _, orient = prior.sample(1000, torch.Generator().manual_seed(2))
    up = orient[:, :, 1]
    assert (up[:, 1] >= torch.cos(torch.deg2rad(torch.tensor(15.0))) - 1e-5).all()
    forward = orient[:, :, 2]
    heading = torch.atan2(forward[:, 0], forward[:, 2])
    histogram = torch.histc(heading, bins=4, min=-torch.pi, max=torch.pi)
    assert (histogram > 150).all()


def test_sampling_is_deterministic_under_the_generator() -> None:
    prior = ProceduralPosePrior()
    first = prior.sample(8, torch.Generator().manual_seed(5))
    second = prior.sample(8, torch.Generator().manual_seed(5))
    third = prior.sample(8, torch.Generator().manual_seed(6))
    torch.testing.assert_close(first, second, rtol=0, atol=0)
    assert not torch.allclose(first[0], third[0])
    assert isinstance(prior, PoseSource)


def test_bad_arguments_are_rejected() -> None:
    with pytest.raises(ValueError, match="max_tilt_deg"):
        ProceduralPosePrior(max_tilt_deg=120)
    with pytest.raises(ValueError, match="lack body joints"):
        ProceduralPosePrior(limits={"left_knee": JOINT_LIMITS["left_knee"]})
    with pytest.raises(ValueError, match="count"):
        ProceduralPosePrior().sample(-1, torch.Generator())

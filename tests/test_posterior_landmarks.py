"""BodyMeshes' hand and foot landmarks in photo pixels: COCO-WholeBody's foot points and
BlazePose's extremities, for the mode and for samples."""

from __future__ import annotations

import pytest
import torch

from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import extremity_landmarks
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import BodyPosterior


@pytest.fixture(scope="module")
def posterior() -> BodyPosterior:
    distribution = BodyDistribution(
        200.0 * torch.eye(3).expand(23, 3, 3),
        torch.zeros(10),
        torch.ones(10) * 0.3,
        FRONTAL_GLOBAL_ORIENT.clone(),
        torch.tensor([0.9, 0.0, 0.0]),
    )
    return BodyPosterior(
        distribution=distribution,
        crop=CropTransform((300.0, 400.0), 600.0, 256), keypoints=torch.zeros(17, 2),
        confidences=torch.ones(17), body=BodyModel(),
    )  # fmt: skip


def test_foot_keypoints_in_photo_pixels_for_mode_and_samples(posterior: BodyPosterior) -> None:
    mode = posterior.mode()
    samples = posterior.sample(5, seed=0)
    assert mode.foot_keypoints2d.shape == (1, 6, 2)
    assert samples.foot_keypoints2d.shape == (5, 6, 2)
    assert mode.extremity_keypoints2d.shape == (1, 10, 2)
    assert samples.extremity_keypoints2d.shape == (5, 10, 2)
    feet = mode.foot_keypoints2d[0]
    ankles = mode.keypoints2d[0, 15:17]  # COCO left, right ankle
    # upright T-pose seen from the front: feet below the ankles (v grows downwards), the left
    # foot's points near the left ankle, and the heels are BlazePose's heels
    assert (feet[:, 1] > ankles[:, 1].min()).all()
    left, right = feet[:3], feet[3:]
    assert (
        torch.linalg.norm(left - ankles[0], dim=-1).max()
        < torch.linalg.norm(left - ankles[1], dim=-1).min()
    )
    assert torch.linalg.norm(right - ankles[1], dim=-1).max() < 60.0
    heels = mode.extremity_keypoints2d[0, 6:8]
    torch.testing.assert_close(feet[[2, 5]], heels)


def test_landmark_pixels_match_the_mesh_reprojected(posterior: BodyPosterior) -> None:
    """The landmarks' pixels are the landmark regressor on the returned mesh, through the same
    camera and crop as the keypoints."""
    mode = posterior.mode()
    points = extremity_landmarks(posterior.body).of_mesh(mode.vertices)  # root-relative
    scale, tx, ty = posterior.camera.tolist()
    ndc = scale * (points[..., :2] + torch.tensor([tx, ty]))
    crop = posterior.crop
    pixels = torch.as_tensor(crop.crop_to_image((ndc + 1) * crop.size / 2 - 0.5))
    torch.testing.assert_close(mode.extremity_keypoints2d, pixels[:, :10].float())
    torch.testing.assert_close(mode.foot_keypoints2d, pixels[:, 10:].float())

"""Posed bodies relative to their pelvis: the frame the weak-perspective camera, the losses and
the metrics work in."""

from __future__ import annotations

import torch

from hkpd.body.body_model import BodyModel

PELVIS = 0
"""Index of the root joint among the body model's 24 joints."""


def pelvis_relative_body(
    body: BodyModel, betas: torch.Tensor, body_pose: torch.Tensor, global_orient: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Pose bodies and return their COCO keypoints and joints relative to the posed pelvis.

    Args:
        body: the body model (keypoint regressor required).
        betas: ``(N, K)``; body_pose ``(N, 23, 3, 3)``; global_orient ``(N, 3, 3)``.

    Returns:
        ``keypoints (N, 17, 3)`` and ``joints (N, 24, 3)``, metres, camera-frame axes when
        ``global_orient`` is body-to-camera.

    Raises:
        ValueError: the body model has no keypoint regressor (an SMPL file).
    """
    posed = body(betas, body_pose, global_orient)
    if posed.keypoints is None:
        raise ValueError(
            "the body model has no keypoint regressor (an SMPL file); COCO keypoints are needed "
            "here: use the shipped hkpd body model"
        )
    pelvis = posed.joints[:, PELVIS : PELVIS + 1]
    return posed.keypoints - pelvis, posed.joints - pelvis

"""Shared helpers (no tests) for the network, loss and metric tests: a hand-made TrainingBatch."""

from __future__ import annotations

import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import (
    CROP_SIZE,
    FRONTAL_GLOBAL_ORIENT,
    SYNTHETIC_FOCAL_PX,
    perspective_project,
)
from hkpd.synthesis.batch import TrainingBatch


def random_rotations(shape: tuple[int, ...], angle_std: float, generator: torch.Generator):
    """``shape + (3, 3)`` rotations with axis-angle components ~ N(0, angle_std²)."""
    return roma.rotvec_to_rotmat(torch.randn(*shape, 3, generator=generator) * angle_std)


def make_training_batch(
    body: BodyModel, batch_size: int, image_size: int = 64, seed: int = 0
) -> TrainingBatch:
    """Bodies with small random poses facing the camera 2.5 m away; random proxies.

    Keypoints are projected with the synthetic perspective camera (focal length scaled with the
    crop) into ``image_size``-pixel crops, the proxy's size, as the synthetic data generator
    does; about 80% of them are marked visible.
    """
    generator = torch.Generator().manual_seed(seed)
    betas = torch.randn(batch_size, 10, generator=generator) * 0.5
    body_pose = random_rotations((batch_size, 23), 0.2, generator)
    global_orient = FRONTAL_GLOBAL_ORIENT @ random_rotations((batch_size,), 0.1, generator)
    jitter = torch.randn(batch_size, 3, generator=generator) * torch.tensor([0.05, 0.05, 0.1])
    translation = torch.tensor([0.0, 0.0, 2.5]) + jitter
    posed = body(betas, body_pose, global_orient, translation)
    focal = SYNTHETIC_FOCAL_PX * image_size / CROP_SIZE
    keypoints2d = perspective_project(posed.keypoints, focal, image_size)
    visible = torch.rand(batch_size, 17, generator=generator) < 0.8
    proxy = torch.rand(batch_size, 18, image_size, image_size, generator=generator)
    return TrainingBatch(
        proxy=proxy,
        body_pose=body_pose,
        global_orient=global_orient,
        betas=betas,
        keypoints2d=keypoints2d,
        visible=visible,
        joints3d=posed.joints,
        translation=translation,
        focal_px=torch.full((batch_size,), SYNTHETIC_FOCAL_PX),
    )

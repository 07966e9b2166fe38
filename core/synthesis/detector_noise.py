"""Detector-like noise on exact 2D keypoints: jitter, misses, confident outliers, left/right swaps.

Used to feed the keypoint-evidence posterior realistic evidence on synthetic images (whose
exact keypoints are known). The defaults reproduce BlazePose against human annotations as
measured on coco_mini's train2017 people (:func:`hkpd.evaluation.detector_errors.detector_errors`;
35 people, 431 visible keypoints): inlier jitter 2.1 % of the person's size per coordinate
(1.75 % of the crop side, which is 1.2× the person), 6.3 % outliers (more than 20 % of the
person's size away), 1.2 % left/right swaps and 9.3 % misses (confidence below 0.6).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS


@dataclass(frozen=True)
class DetectorNoise:
    """The noise model (fractions of the crop side; rates per keypoint or per pair).

    Attributes:
        sigma: Gaussian jitter per coordinate.
        outlier_rate: share of keypoints replaced by a point displaced uniformly in a square of
            half-side ``outlier_scale``.
        outlier_scale: see ``outlier_rate``.
        swap_rate: share of left/right pairs reported swapped.
        miss_rate: share of visible keypoints not reported.
    """

    sigma: float = 0.0175
    outlier_rate: float = 0.063
    outlier_scale: float = 0.3
    swap_rate: float = 0.012
    miss_rate: float = 0.093


def detector_like_keypoints(
    keypoints: torch.Tensor,
    visible: torch.Tensor,
    crop_size: int,
    noise: DetectorNoise,
    generator: torch.Generator,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Corrupt exact keypoints as a detector would.

    Args:
        keypoints: ``(B, 17, 2)`` exact keypoints, crop pixels.
        visible: ``(B, 17)`` bool; hidden keypoints are never reported.
        crop_size: crop side in pixels.
        noise: the noise model.
        generator: a CPU generator (results do not depend on the device).

    Returns:
        ``(detected (B, 17, 2), reported (B, 17) bool)`` on ``keypoints``' device.
    """
    device = keypoints.device
    points = keypoints.detach().cpu().double().clone()
    batch = points.shape[0]
    for left, right in COCO17_LEFT_RIGHT_PAIRS:
        swap = torch.rand(batch, generator=generator) < noise.swap_rate
        first, second = points[swap, left].clone(), points[swap, right].clone()
        points[swap, left], points[swap, right] = second, first
    jitter = torch.randn(points.shape, generator=generator, dtype=points.dtype)
    points += jitter * noise.sigma * crop_size
    outlier = torch.rand(points.shape[:2], generator=generator) < noise.outlier_rate
    offset = torch.rand(points.shape, generator=generator, dtype=points.dtype) * 2 - 1
    points = torch.where(
        outlier[..., None], points + offset * noise.outlier_scale * crop_size, points
    )
    missed = torch.rand(points.shape[:2], generator=generator) < noise.miss_rate
    reported = visible.detach().cpu().bool() & ~missed
    return points.to(device=device, dtype=keypoints.dtype), reported.to(device)

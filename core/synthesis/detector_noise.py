"""Detector-like noise on exact 2D keypoints: jitter, misses, confident outliers, left/right swaps.

Used to feed the keypoint-evidence posterior realistic evidence on synthetic images (whose
exact keypoints are known). The defaults reproduce BlazePose against human annotations as
measured on coco_mini's train2017 people (:func:`hkpd.evaluation.detector_errors.detector_errors`;
35 people, 431 visible keypoints): inlier jitter 2.1 % of the person's size per coordinate
(1.75 % of the crop side, which is 1.2× the person), 6.3 % outliers (more than 20 % of the
person's size away), 1.2 % left/right swaps and 9.3 % misses (confidence below 0.6).

BlazePose's hand and foot landmarks (:mod:`hkpd.body.extremity_landmarks`) get the same kinds of
noise through :func:`detector_like_extremities`, their jitter scaled by their spread relative to
the keypoints' as measured on synthetic renders (``docs/experiments/
extremity_landmark_noise.py``: 1.85× on the hands, 1.55× on the feet) and their outlier rates as
measured there (2.6 %, 6.9 %); no real annotations of them were at hand, so the misses are the
keypoints'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from hkpd.body.extremity_landmarks import EXTREMITY_MIRROR
from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS

EXTREMITY_LEFT_RIGHT_PAIRS = tuple(
    (index, other) for index, other in enumerate(EXTREMITY_MIRROR) if index < other
)
"""Left/right pairs of BlazePose's ten hand and foot landmarks (rows of their array)."""

HAND_ROWS = slice(0, 6)
FOOT_ROWS = slice(6, 10)


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
    pairs: Sequence[tuple[int, int]] = COCO17_LEFT_RIGHT_PAIRS,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Corrupt exact keypoints as a detector would.

    Args:
        keypoints: ``(B, 17, 2)`` exact keypoints, crop pixels (or ``(B, P, 2)`` other points
            with their ``pairs``).
        visible: ``(B, 17)`` bool; hidden keypoints are never reported.
        crop_size: crop side in pixels.
        noise: the noise model.
        generator: a CPU generator (results do not depend on the device).
        pairs: the left/right pairs that may be reported swapped.

    Returns:
        ``(detected (B, 17, 2), reported (B, 17) bool)`` on ``keypoints``' device.
    """
    device = keypoints.device
    points = keypoints.detach().cpu().double().clone()
    batch = points.shape[0]
    for left, right in pairs:
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


HAND_NOISE = DetectorNoise(sigma=0.0175 * 1.85, outlier_rate=0.026)
"""Detector-like noise of the hand landmarks (see the module docstring)."""

FOOT_NOISE = DetectorNoise(sigma=0.0175 * 1.55, outlier_rate=0.069)
"""Detector-like noise of the foot landmarks (see the module docstring)."""


def detector_like_extremities(
    landmarks: torch.Tensor,
    visible: torch.Tensor,
    crop_size: int,
    generator: torch.Generator,
    hand_noise: DetectorNoise = HAND_NOISE,
    foot_noise: DetectorNoise = FOOT_NOISE,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Corrupt BlazePose's ten exact hand and foot landmarks as the detector would: the hands'
    and the feet's noise drawn separately (:func:`detector_like_keypoints`, their left/right
    pairs swapped at their rates).

    Args:
        landmarks: ``(B, 10, 2)`` exact landmarks, crop pixels
            (:data:`hkpd.body.extremity_landmarks.BLAZEPOSE_EXTREMITY_NAMES` order).
        visible: ``(B, 10)`` bool; hidden landmarks are never reported.
        crop_size: crop side in pixels.
        generator: a CPU generator.
        hand_noise, foot_noise: the two groups' noise models.

    Returns:
        ``(detected (B, 10, 2), reported (B, 10) bool)`` on ``landmarks``' device.
    """
    if landmarks.ndim != 3 or tuple(landmarks.shape[1:]) != (10, 2):
        raise ValueError(f"expected (B, 10, 2) landmarks, got {tuple(landmarks.shape)}")
    detected, reported = [], []
    for rows, noise in ((HAND_ROWS, hand_noise), (FOOT_ROWS, foot_noise)):
        offset = rows.start
        pairs = [
            (a - offset, b - offset)
            for a, b in EXTREMITY_LEFT_RIGHT_PAIRS
            if rows.start <= a < rows.stop
        ]
        points, shown = detector_like_keypoints(
            landmarks[:, rows], visible[:, rows], crop_size, noise, generator, pairs
        )
        detected.append(points)
        reported.append(shown)
    return torch.cat(detected, 1), torch.cat(reported, 1)

"""How much BlazePose's keypoints move when it looks at the person again from a slightly
different crop: a sign of a reading that should not be trusted (issue 51's quality score).

The landmark model reads a square region around the person (:class:`Region`). A person it sees
clearly is placed in the same spot whatever the region's exact position; a small, blurred or
crowded person, or a neighbour taken for them, moves. :func:`landmark_spread` reads the region
again, moved by a few percent of its side (:data:`SPREAD_REGIONS`), and returns how far the 17
COCO keypoints moved, on average, as a fraction of the person's size. Alone, this number tells
readings off by more than 0.2 of the person's size from the rest with an AUROC of 0.95 on
coco_mini train2017 people read through their annotated boxes and 0.84 on val2017's (a region
grown by a fifth instead did as well, both together no better: ``docs/prediction.md``,
"Quality score").

It costs one landmark-model run without the segmentation head: +19 ms a detection on one CPU
core (median over 11 photos, ``benchmarks/bench_landmark_spread.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from hkpd.prediction.detection.blazepose import REGION_SCALE, PoseLandmarks
from hkpd.prediction.detection.warp import Region
from hkpd.proxy import CONFIDENCE_THRESHOLD

SPREAD_REGIONS: tuple[tuple[float, float, float], ...] = ((0.08, 0.06, 1.0),)
"""The regions read again, each ``(dx, dy, scale)``: the centre moved by ``(dx, dy)`` × the
region's side (photo axes) and the side multiplied by ``scale``."""


class LandmarkRunner(Protocol):
    """The part of a pose model :func:`landmark_spread` needs (:class:`BlazePose`)."""

    def landmarks(
        self, pixels: np.ndarray, region: Region, segmentation: bool = False
    ) -> PoseLandmarks: ...


def landmark_spread(
    runner: LandmarkRunner, pixels: np.ndarray, found: PoseLandmarks, coco: Sequence[int]
) -> float:
    """Mean movement of the keypoints when the landmark model reads ``found``'s region again.

    Args:
        runner: the pose model that made ``found``.
        pixels: ``(H, W, 3)`` uint8 RGB, the pixels ``found`` was read from.
        found: the landmarks as first read (their ``region`` is moved).
        coco: the 17 BlazePose landmark indices of the COCO keypoints, COCO order.

    Returns:
        The keypoints' displacement between the first reading and each of
        :data:`SPREAD_REGIONS`' readings, weighted by the first reading's ``(17,)``
        visibilities, averaged over the regions, divided by the person's size (the confident
        keypoints' longer extent; the region's side / 1.25 when fewer than two are confident):
        a fraction, 0 when nothing moves.
    """
    indices = list(coco)
    first = found.points[indices]  # (17, 2) pixels
    visibility = np.clip(found.visibility[indices], 0.0, 1.0)
    total = float(visibility.sum())
    weights = visibility / total if total > 0 else np.full(len(indices), 1.0 / len(indices))
    moved = []
    for dx, dy, scale in SPREAD_REGIONS:
        region = _moved(found.region, dx, dy, scale)
        again = runner.landmarks(pixels, region, False).points[indices]
        moved.append(float((np.linalg.norm(again - first, axis=-1) * weights).sum()))
    return float(np.mean(moved)) / _person_size(first, visibility, found.region)


def _moved(region: Region, dx: float, dy: float, scale: float) -> Region:
    """``region`` with its centre moved by ``(dx, dy)`` × its side and its side × ``scale``."""
    shift = np.array([dx, dy], np.float64) * region.size
    return Region(np.asarray(region.centre, np.float64) + shift, region.size * scale, region.angle)


def _person_size(points: np.ndarray, visibility: np.ndarray, region: Region) -> float:
    """The ``(17, 2)`` keypoints' longer extent over those with ``(17,)`` visibility >= 0.6,
    pixels (the region's side / 1.25 when fewer than two are)."""
    confident = points[visibility >= CONFIDENCE_THRESHOLD]
    if len(confident) >= 2:
        return max(float(np.ptp(confident, axis=0).max()), 1.0)
    return max(region.size / REGION_SCALE, 1.0)

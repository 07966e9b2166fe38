"""How far BlazePose's keypoints move on a second look (``landmark_spread``)."""

from __future__ import annotations

import numpy as np
import pytest

from hkpd.prediction.detection.blazepose import PoseLandmarks
from hkpd.prediction.detection.keypoint_detector import COCO_FROM_BLAZEPOSE
from hkpd.prediction.detection.landmark_spread import SPREAD_REGIONS, landmark_spread
from hkpd.prediction.detection.warp import Region

PIXELS = np.zeros((400, 400, 3), np.uint8)
LAYOUT = np.random.default_rng(0).uniform(-0.3, 0.3, size=(33, 2))
"""Where the stand-in landmark model puts the 33 landmarks, in units of the region's side."""


class RegionBoundRunner:
    """A landmark model that draws the same figure inside whatever region it is shown (a
    person it cannot pin down) or, with ``steady``, always at the first region's place."""

    def __init__(self, steady: bool) -> None:
        self.steady = steady
        self.regions: list[Region] = []

    def landmarks(self, pixels, region: Region, segmentation: bool = False) -> PoseLandmarks:
        self.regions.append(region)
        anchor = self.regions[0] if self.steady else region
        points = np.asarray(anchor.centre) + LAYOUT * anchor.size
        return PoseLandmarks(points, np.full(33, 0.9), 1.0, region, None)


def first_reading(runner: RegionBoundRunner) -> PoseLandmarks:
    return runner.landmarks(PIXELS, Region(np.array([200.0, 200.0]), 250.0, 0.0))


def test_a_person_read_in_the_same_place_has_no_spread() -> None:
    runner = RegionBoundRunner(steady=True)
    found = first_reading(runner)
    assert landmark_spread(runner, PIXELS, found, COCO_FROM_BLAZEPOSE) == 0.0
    assert len(runner.regions) == 1 + len(SPREAD_REGIONS)
    assert all(region is not runner.regions[0] for region in runner.regions[1:])


def test_keypoints_that_follow_the_crop_spread_by_its_move_over_the_persons_size() -> None:
    runner = RegionBoundRunner(steady=False)
    found = first_reading(runner)
    spread = landmark_spread(runner, PIXELS, found, COCO_FROM_BLAZEPOSE)
    coco = found.points[list(COCO_FROM_BLAZEPOSE)]
    size = float(np.ptp(coco, axis=0).max())
    layout = LAYOUT[list(COCO_FROM_BLAZEPOSE)] * 250.0  # (17, 2) pixels from the centre
    moves = [
        np.linalg.norm(np.array([dx, dy]) * 250.0 + (scale - 1.0) * layout, axis=-1).mean()
        for dx, dy, scale in SPREAD_REGIONS
    ]
    expected = float(np.mean(moves))
    assert spread == pytest.approx(expected / size, rel=1e-9)
    assert spread > 0.05

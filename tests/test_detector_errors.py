"""The detector error statistics count misses, swaps and outliers and measure the jitter."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hkpd.evaluation.detector_errors import detector_errors
from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.prediction.detection.keypoint_detector import KeypointDetection


class OffsetDetector:
    """Returns each person's annotation moved by a fixed offset, with one swap, miss, outlier."""

    def __init__(self, people, offset: float) -> None:
        self.by_path = {str(p.image_path): p for p in people}
        self.offset = offset

    def detect(self, image, bbox=None) -> KeypointDetection:
        person = self.by_path[image]
        points = person.keypoints + self.offset
        confidences = np.full(17, 0.9)
        confidences[0] = 0.1  # nose missed
        points[[7, 8]] = person.keypoints[[8, 7]]  # elbows swapped
        points[15] += 60.0  # left ankle far off
        return KeypointDetection(points, confidences, person.bbox, None, None, (640, 480), 0.0)


def test_counts_and_jitter_match_what_was_planted() -> None:
    rng = np.random.default_rng(0)
    people = []
    for index in range(4):
        keypoints = np.stack([rng.uniform(100, 200, 17), np.linspace(100, 300, 17)], 1)
        keypoints[8] = keypoints[7] + [40.0, 0.0]  # elbows well apart
        bbox = np.array([90.0, 90.0, 290.0, 310.0])  # larger side 220 px
        people.append(AnnotatedPerson(Path(f"p{index}.jpg"), bbox, keypoints, np.ones(17, bool)))
    stats = detector_errors(OffsetDetector(people, offset=2.2), people)
    assert stats.people == 4 and stats.keypoints == 68
    assert stats.miss_rate == 1 / 17 and stats.swap_rate == 2 / 17 and stats.outlier_rate == 1 / 17
    expected = np.hypot(2.2, 2.2) / 220
    assert abs(stats.per_keypoint_median["left_wrist"] - expected) < 1e-9

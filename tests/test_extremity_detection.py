"""BlazePose's hand and foot landmarks through detection and the network input: kept with
their visibilities, mapped to the photo and the crop as the keypoints are, dropped under
occluders."""

from __future__ import annotations

import numpy as np

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_INDICES
from hkpd.prediction import KeypointDetector, prepare_network_input
from hkpd.prediction.detection.blazepose import PersonCandidate, PoseLandmarks
from hkpd.prediction.detection.warp import Region


class FigureRunner:
    """Stands in for BlazePose: one person whose 33 landmarks lie on a grid in the middle of
    the photo, each landmark's visibility ``0.3 + 0.02 * index``."""

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        height, width = pixels.shape[:2]
        centre = np.array([width / 2, height / 2])
        box = np.r_[centre - 50, centre + 50]
        return [PersonCandidate(0.9, box, np.tile(centre, (4, 1)), Region(centre, 300.0, 0.0))]

    def landmarks(self, pixels, region, segmentation=False) -> PoseLandmarks:
        index = np.arange(33)
        points = region.centre + np.stack([(index % 6) * 30.0 - 75, (index // 6) * 40.0 - 110], 1)
        return PoseLandmarks(points, 0.3 + 0.02 * index, 0.99, region, None)


def photo() -> np.ndarray:
    return np.full((480, 640, 3), 128, np.uint8)


def test_detection_keeps_the_ten_extremities_with_their_visibilities() -> None:
    detection = KeypointDetector(runner=FigureRunner(), segmentation=False).detect(photo())
    indices = np.array(BLAZEPOSE_EXTREMITY_INDICES)
    index = np.arange(33)
    expected = np.array([320.0, 240.0]) + np.stack(
        [(index % 6) * 30.0 - 75, (index // 6) * 40.0 - 110], 1
    )
    assert detection.extremities is not None and detection.extremity_confidences is not None
    np.testing.assert_allclose(detection.extremities, expected[indices])
    np.testing.assert_allclose(detection.extremity_confidences, 0.3 + 0.02 * indices)


def test_extremities_map_to_the_crop_and_drop_under_occluders() -> None:
    detector = KeypointDetector(runner=FigureRunner(), segmentation=False)
    clear = prepare_network_input(photo(), detector)
    assert clear.extremities_crop is not None and clear.extremity_evidence is not None
    detection = clear.detection
    np.testing.assert_allclose(
        clear.extremities_crop, clear.crop.image_to_crop(detection.extremities)
    )
    # confident (>= 0.6: index 17 has 0.64) extremities are evidence with nothing over them
    np.testing.assert_array_equal(clear.extremity_evidence, detection.extremity_confidences >= 0.6)
    # a box over the left heel (landmark 29, the 7th extremity) drops it and nothing else
    heel = detection.extremities[6]
    box = np.r_[heel - 5, heel + 5]
    covered = prepare_network_input(photo(), detector, occluders=[box])
    assert covered.extremity_evidence is not None
    expected = clear.extremity_evidence.copy()
    expected[6] = False
    assert clear.extremity_evidence[6]
    np.testing.assert_array_equal(covered.extremity_evidence, expected)
    np.testing.assert_array_equal(covered.evidence, clear.evidence)  # no keypoint under it

"""The two keypoint readers as one observation for the fit (issue 59 part 3)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hkpd.prediction.detection.movenet import SecondReading
from hkpd.prediction.detection.warp import Region
from hkpd.prediction.second_evidence import (
    MIN_SECOND_SCORE,
    SECOND_READER_WEIGHT,
    combined_keypoint_evidence,
)


class _HalfScale:
    """A crop twice as coarse as the photo, shifted by (10, 20)."""

    def image_to_crop(self, points):
        return (np.asarray(points) - [10.0, 20.0]) / 2


def _prepared(first: np.ndarray, second: np.ndarray | None, scores: np.ndarray | None = None):
    reading = None
    if second is not None:
        scores = np.full(17, 0.9) if scores is None else scores
        reading = SecondReading(second, scores, Region(np.zeros(2), 1.0, 0.0), 0.0)
    detection = SimpleNamespace(
        keypoints=first, person_box=np.array([0.0, 0.0, 200.0, 200.0]), second_reading=reading
    )
    crop = _HalfScale()
    return SimpleNamespace(
        keypoints_crop=crop.image_to_crop(first),
        evidence=np.ones(17, bool),
        detection=detection,
        crop=crop,
    )


def _body() -> np.ndarray:
    return np.random.default_rng(1).uniform(20, 180, (17, 2))


def test_agreed_keypoints_are_the_readers_weighted_mean_and_disputed_ones_no_evidence() -> None:
    first = _body()
    second = first + 4.0  # 0.028 of the 200-px person: agreed
    second[9] += 60.0  # the left wrist: disputed (0.3 of the size)
    scores = np.full(17, 0.9)
    scores[3] = MIN_SECOND_SCORE / 2  # the left ear: Thunder unsure
    keypoints, evidence = combined_keypoint_evidence(_prepared(first, second, scores))
    crop_first = (first - [10.0, 20.0]) / 2
    expected = crop_first + SECOND_READER_WEIGHT * 2.0  # 4 photo px = 2 crop px
    agreed = [k for k in range(17) if k not in (3, 9)]
    np.testing.assert_allclose(keypoints[agreed], expected[agreed])
    np.testing.assert_allclose(keypoints[[3, 9]], crop_first[[3, 9]])
    assert evidence.tolist() == [k != 9 for k in range(17)]


def test_without_a_second_reading_or_when_most_of_the_body_is_disputed_blazepose_stands() -> None:
    first = _body()
    prepared = _prepared(first, None)
    keypoints, evidence = combined_keypoint_evidence(prepared)
    np.testing.assert_array_equal(keypoints, prepared.keypoints_crop)
    assert evidence.all()
    elsewhere = _prepared(first, first + 100.0)  # another person
    keypoints, evidence = combined_keypoint_evidence(elsewhere)
    np.testing.assert_array_equal(keypoints, elsewhere.keypoints_crop)
    assert evidence.all()


def test_a_disputed_wrist_takes_its_hand_landmarks_out_of_the_evidence() -> None:
    from hkpd.prediction.second_evidence import landmark_evidence

    first = _body()
    second = first + 4.0
    second[9] += 60.0  # the left wrist disputed
    prepared = _prepared(first, second)
    prepared.extremity_evidence = np.ones(10, bool)
    prepared.extremity_evidence[7] = False  # the right heel was not evidence anyway
    kept = landmark_evidence(prepared)
    # left pinky, index and thumb (0, 2, 4) hang from the left wrist
    assert kept.tolist() == [k not in (0, 2, 4, 7) for k in range(10)]
    prepared.extremity_evidence = None
    assert landmark_evidence(prepared) is None

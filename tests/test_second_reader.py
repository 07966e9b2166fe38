"""The second keypoint reader (MoveNet Thunder) and how the two readers' agreement is measured
(issue 59)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.assets import shipped_file
from hkpd.coco_keypoints import COCO17_MIRROR_ORDER
from hkpd.prediction.detection.keypoint_detector import KeypointDetection, KeypointDetector
from hkpd.prediction.detection.movenet import (
    MOVENET_INPUT_SIZE,
    PERSON_BOX_PADDING,
    SecondReader,
    reading_region,
)
from hkpd.prediction.image_input import load_image
from hkpd.prediction.reader_agreement import DISAGREE_FRACTION, reader_agreement


def _detection(box: tuple[float, float, float, float], size: tuple[int, int]) -> KeypointDetection:
    return KeypointDetection(
        keypoints=np.zeros((17, 2)),
        confidences=np.ones(17),
        person_box=np.asarray(box, np.float64),
        mask_box=None,
        search_box=None,
        image_size=size,
        seconds=0.0,
    )


def _body(size: float = 100.0) -> np.ndarray:
    """(17, 2) a standing person's keypoints, left side at larger u (facing the camera)."""
    rng = np.random.default_rng(0)
    points = rng.uniform(0, size, (17, 2))
    for left, right in ((5, 6), (7, 8), (9, 10), (11, 12), (13, 14), (15, 16), (1, 2), (3, 4)):
        points[left, 0], points[right, 0] = size * 0.7, size * 0.3
    return points


def test_identical_readings_agree_and_a_swapped_reading_fails_the_swap_test() -> None:
    body = _body()
    same = reader_agreement(body, body, 100.0)
    assert same.mean_distance == 0 and same.swap_gain < 0 and same.torso_offset == 0
    assert not same.disputed.any()
    swapped = reader_agreement(body, body[list(COCO17_MIRROR_ORDER)], 100.0)
    assert swapped.swap_gain > 0.3 and swapped.disputed_share > 0.5
    assert swapped.torso_offset < 1e-9  # the same torso, sides traded


def test_a_reading_of_another_person_is_far_off_in_the_torso() -> None:
    body = _body()
    moved = reader_agreement(body, body + np.array([80.0, 0.0]), 100.0)
    assert moved.torso_offset == pytest.approx(0.8)
    assert moved.disputed.all() and moved.signals()["readers_disputed_share"] == 1.0
    one_limb = body.copy()
    one_limb[9] += [2 * DISAGREE_FRACTION * 100, 0]
    assert reader_agreement(body, one_limb, 100.0).disputed.nonzero()[0].tolist() == [9]


def test_keypoints_are_mapped_back_to_the_original_photos_pixels() -> None:
    """A stand-in model answering (y, x) = (0.25, 0.75) everywhere: the point a quarter down
    and three quarters across the padded square around the person's box, in original pixels,
    also when the photo was downscaled to load."""
    answer = torch.tensor([0.25, 0.75, 0.9]).repeat(17, 1)[None, None]
    seen = []

    def model(pixels: torch.Tensor) -> torch.Tensor:
        seen.append(pixels)
        return answer

    photo = np.zeros((800, 1200, 3), np.uint8)
    loaded = load_image(photo, max_side=600)  # half size
    detection = _detection((400, 200, 600, 600), (1200, 800))
    second = SecondReader(model).read(loaded, detection)
    side = 400 * PERSON_BOX_PADDING
    expected = np.array([500 + 0.25 * side, 400 - 0.25 * side])
    np.testing.assert_allclose(second.keypoints, np.tile(expected, (17, 1)), atol=1.0)
    assert seen[0].shape == (1, MOVENET_INPUT_SIZE, MOVENET_INPUT_SIZE, 3)
    assert seen[0].dtype == torch.int32
    np.testing.assert_allclose(second.scores, 0.9, atol=1e-6)
    on_box = reading_region(loaded, detection, bbox=(0, 0, 1200, 800))
    np.testing.assert_allclose(on_box.centre, [300, 200])  # working pixels


def test_thunder_agrees_with_blazepose_on_the_shipped_photo() -> None:
    """The real models on the shipped CC0 lunge: the two independent readers agree within
    a tenth of the person's size on average, and neither reads the sides the other way."""
    torch.set_num_threads(1)
    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "reinstall")
    loaded = load_image(photo)
    with KeypointDetector() as detector:
        detection = detector.detect(loaded)
    second = SecondReader().read(loaded, detection)
    size = float((detection.person_box[2:] - detection.person_box[:2]).max())
    agreement = reader_agreement(detection.keypoints, second.keypoints, size)
    assert agreement.mean_distance < 0.1, agreement
    assert agreement.swap_gain < 0 and agreement.torso_offset < 0.05
    assert (second.scores > 0.3).sum() >= 12


def test_a_face_the_second_reader_does_not_see_makes_the_facing_ambiguous() -> None:
    """Back views: MoveNet scores the nose and eyes low (quality's facing note)."""
    from types import SimpleNamespace

    from hkpd.prediction.quality import SECOND_FACE_SCORE, _second_reader_sees_no_face

    def posterior(scores):
        second = None if scores is None else SimpleNamespace(scores=np.asarray(scores))
        detection = SimpleNamespace(second_reading=second)
        return SimpleNamespace(network_input=SimpleNamespace(detection=detection))

    seen = np.full(17, 0.8)
    unseen = seen.copy()
    unseen[2] = SECOND_FACE_SCORE / 2  # the right eye
    assert not _second_reader_sees_no_face(posterior(seen))
    assert _second_reader_sees_no_face(posterior(unseen))
    assert not _second_reader_sees_no_face(posterior(None))  # second_reader=False

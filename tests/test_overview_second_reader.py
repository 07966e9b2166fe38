"""The overview marks where the second keypoint reader disagrees (issue 59): a magenta cross at
its disputed keypoints, none where it agrees."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from hkpd.prediction.crop import CropTransform
from hkpd.prediction.exports.overview import SECOND_READER_COLOUR, Outlines, draw_skeletons
from hkpd.prediction.image_input import load_image
from hkpd.prediction.reader_agreement import second_reader_outline


def _magenta(pixels: np.ndarray) -> np.ndarray:
    return (np.abs(pixels.astype(int) - np.array(SECOND_READER_COLOUR)).sum(-1) < 60).sum()


def test_only_disputed_keypoints_of_the_second_reader_are_marked() -> None:
    photo = load_image(np.full((200, 200, 3), 90, np.uint8))
    crop = CropTransform((100.0, 100.0), 180.0, 256)
    keypoints = np.random.default_rng(0).uniform(60, 140, (17, 2))
    second = keypoints + 1.0
    second[9] = (25.0, 25.0)  # the left wrist elsewhere
    detection = SimpleNamespace(
        keypoints=keypoints,
        person_box=np.array([50.0, 50.0, 150.0, 150.0]),
        second_reading=SimpleNamespace(keypoints=second, scores=np.full(17, 0.9)),
    )
    fields = second_reader_outline(detection)
    assert fields["second_disputed"].tolist() == [k == 9 for k in range(17)]
    outlines = Outlines(**fields)
    assert outlines.shows_second_reader
    drawn = draw_skeletons(photo, crop, keypoints, np.ones(17), keypoints, None, 200, outlines)
    plain = draw_skeletons(photo, crop, keypoints, np.ones(17), keypoints, None, 200, Outlines())
    view = CropTransform(crop.centre, crop.side, 200)
    u, v = np.round(view.image_to_crop(second[9])).astype(int)
    assert _magenta(drawn[v - 3 : v + 4, u - 3 : u + 4]) > 5
    assert _magenta(plain) == 0
    assert second_reader_outline(SimpleNamespace(second_reading=None)) == {}

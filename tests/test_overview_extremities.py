"""The overview's photo panel draws the hand and foot landmarks when given them."""

from __future__ import annotations

import numpy as np

from hkpd.prediction.crop import CropTransform
from hkpd.prediction.exports.overview import Outlines, draw_skeletons
from hkpd.prediction.image_input import load_image


def test_landmarks_and_mode_bones_are_drawn_where_given() -> None:
    photo = load_image(np.full((200, 200, 3), 90, np.uint8))
    crop = CropTransform((100.0, 100.0), 180.0, 256)
    rng = np.random.default_rng(0)
    keypoints = rng.uniform(40, 160, (17, 2))
    confidences = np.ones(17)
    extremities = np.array([[20.0 + 15 * i, 185.0] for i in range(10)])  # a row near the bottom
    shown = np.ones(10, dtype=bool)
    shown[3] = False
    plain = draw_skeletons(photo, crop, keypoints, confidences, keypoints, None, 200, Outlines())
    drawn = draw_skeletons(
        photo, crop, keypoints, confidences, keypoints, None, 200,
        Outlines(detected_extremities=extremities, extremity_shown=shown,
                 mode_extremities2d=extremities),
    )  # fmt: skip
    view = CropTransform(crop.centre, crop.side, 200)
    for index, (u, v) in enumerate(np.round(view.image_to_crop(extremities)).astype(int)):
        patch_plain, patch = (
            plain[v - 1 : v + 2, u - 1 : u + 2],
            drawn[v - 1 : v + 2, u - 1 : u + 2],
        )
        assert not np.array_equal(patch_plain, patch)
        if index != 3:  # a shown landmark is a white square
            assert drawn[v, u].min() > 200

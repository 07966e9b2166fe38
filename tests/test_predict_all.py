"""Every person of a photo in one call, several photos in one call (issue 51)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from PIL import Image

from hkpd.assets import shipped_file
from hkpd.prediction import Predictor
from hkpd.prediction.detection.keypoint_detector import people_by_size

PHOTO = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")


def test_people_are_ranked_by_box_area_keeping_ties_in_order() -> None:
    people = [SimpleNamespace(person_box=box) for box in
              [(0, 0, 10, 10), (0, 0, 50, 40), (5, 5, 15, 15), (0, 0, 1, 1)]]  # fmt: skip
    ranked = people_by_size(people)  # type: ignore[arg-type]
    assert [p.person_box for p in ranked] == [
        (0, 0, 50, 40), (0, 0, 10, 10), (5, 5, 15, 15), (0, 0, 1, 1)
    ]  # fmt: skip


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    torch.set_num_threads(1)
    return Predictor.from_pretrained(device="cpu")


def _two_people() -> np.ndarray:
    """The shipped photo beside a half-size copy of it: a large and a small person."""
    photo = np.asarray(Image.open(PHOTO).convert("RGB"))
    small = np.asarray(Image.fromarray(photo).resize((photo.shape[1] // 2, photo.shape[0] // 2)))
    canvas = np.full((photo.shape[0], photo.shape[1] + small.shape[1], 3), 255, np.uint8)
    canvas[:, : photo.shape[1]] = photo
    canvas[-small.shape[0] :, photo.shape[1] :] = small
    return canvas


@pytest.mark.slow
def test_predict_all_gives_one_posterior_per_person_larger_first(predictor: Predictor) -> None:
    canvas = _two_people()
    posteriors = predictor.predict_all(canvas, sex="male")
    assert len(posteriors) == 2
    boxes = [p.person_box for p in posteriors]
    assert all(isinstance(box, tuple) and len(box) == 4 for box in boxes)
    assert boxes == [tuple(float(v) for v in p.network_input.detection.person_box)
                     for p in posteriors]  # fmt: skip
    areas = [(b[2] - b[0]) * (b[3] - b[1]) for b in boxes]
    assert areas[0] > 2 * areas[1]
    assert boxes[1][0] > canvas.shape[1] * 0.6  # the small copy is on the right
    assert all(p.sex_probabilities == {"female": 0.0, "male": 1.0} for p in posteriors)
    with pytest.raises(ValueError, match="drop bbox"):
        predictor.predict_all(canvas, bbox=(0, 0, 10, 10))
    assert predictor.predict_all(np.full((300, 300, 3), 255, np.uint8)) == []


def test_predict_many_keeps_the_photos_order(predictor: Predictor) -> None:
    one, two = predictor.predict_many([PHOTO, PHOTO], evidence=False)
    assert torch.equal(one.F, two.F) and one.source == two.source == "network"
    x0, y0, x1, y1 = one.person_box  # photo pixels (the 1080 x 720 photo): the lunging woman
    assert 0 <= x0 < x1 <= 1080 and 0 <= y0 < y1 <= 720 and x1 - x0 > 300

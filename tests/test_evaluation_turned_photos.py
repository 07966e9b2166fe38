"""Quarter turns of annotated photos: points follow their pixels, files are lossless."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from hkpd.evaluation.cli import main as eval_main
from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.evaluation.turned_photos import QUARTER_TURNS, turn_points, turned_person


@pytest.fixture
def person(tmp_path) -> AnnotatedPerson:
    rng = np.random.default_rng(4)
    pixels = rng.integers(0, 256, (40, 60, 3), dtype=np.uint8)  # 60 wide, 40 high
    (tmp_path / "split").mkdir()
    path = tmp_path / "split" / "photo.png"
    Image.fromarray(pixels).save(path)
    keypoints = np.stack([rng.integers(0, 60, 17), rng.integers(0, 40, 17)], 1).astype(float)
    outline = np.array([[2.0, 3.0], [40.0, 3.0], [40.0, 25.0]])
    return AnnotatedPerson(
        path, np.array([5.0, 2.0, 44.0, 27.0]), keypoints, np.ones(17, bool), (outline,), (60, 40)
    )


@pytest.mark.parametrize("degrees", QUARTER_TURNS)
def test_turned_points_land_on_the_same_pixels(person, tmp_path, degrees) -> None:
    original = np.asarray(Image.open(person.image_path))
    turned = turned_person(person, degrees, tmp_path)
    pixels = np.asarray(Image.open(turned.image_path))
    width, height = turned.image_size
    assert pixels.shape == (height, width, 3)
    assert (width, height) == ((40, 60) if degrees != 180 else (60, 40))
    for (u, v), (tu, tv) in zip(person.keypoints, turned.keypoints, strict=True):
        np.testing.assert_array_equal(pixels[int(tv), int(tu)], original[int(v), int(u)])
    # The box still holds every point it held.
    inside = turn_points(np.array([[5.0, 2.0], [44.0, 27.0], [20.0, 10.0]]), degrees, 60, 40)
    assert (inside >= turned.bbox[:2]).all() and (inside <= turned.bbox[2:]).all()
    assert turned.outlines[0].shape == (3, 2)
    np.testing.assert_array_equal(turned.visible, person.visible)
    assert turned.image_path.parent == tmp_path and turned.image_path.suffix == ".png"


def test_four_quarter_turns_come_back_and_other_angles_are_refused(person, tmp_path) -> None:
    points = person.keypoints
    once = turn_points(points, 90, 60, 40)
    twice = turn_points(once, 90, 40, 60)
    np.testing.assert_array_equal(twice, turn_points(points, 180, 60, 40))
    np.testing.assert_array_equal(turn_points(twice, 180, 60, 40), points)
    np.testing.assert_array_equal(turn_points(once, 270, 40, 60), points)
    with pytest.raises(ValueError, match="90, 180 or 270"):
        turn_points(points, 45, 60, 40)
    with pytest.raises(ValueError, match="90, 180 or 270"):
        turned_person(person, 0, tmp_path)


def test_eval_refuses_turns_without_photos(capsys) -> None:
    assert eval_main(["missing_is_checked_later.pt", "--coco-turns", "--no-synthetic"]) == 2

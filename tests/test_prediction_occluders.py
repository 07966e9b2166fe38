"""Occluders and apply_occluders: slicing semantics, clipping, original-photo coordinates,
validation once at the boundary."""

from __future__ import annotations

import numpy as np
import pytest

from hkpd.prediction import Occluders, apply_occluders, load_image, points_under_boxes


def grey_image(height: int = 60, width: int = 80) -> np.ndarray:
    return np.full((height, width, 3), 200, np.uint8)


def test_integer_box_blacks_out_exactly_the_slice_and_leaves_the_input_alone() -> None:
    image = grey_image()
    out = apply_occluders(image, [(10, 20, 30, 25)])
    expected = image.copy()
    expected[20:25, 10:30] = 0
    np.testing.assert_array_equal(out, expected)
    assert (image == 200).all()  # a copy, not in place


def test_fractional_boxes_cover_every_touched_pixel_and_several_boxes_add_up() -> None:
    out = apply_occluders(grey_image(), np.array([[10.2, 5.0, 12.5, 6.0], [70, 50, 75, 55]]))
    black = ~out.any(-1)
    expected = np.zeros((60, 80), bool)
    expected[5:6, 10:13] = True
    expected[50:55, 70:75] = True
    np.testing.assert_array_equal(black, expected)


def test_boxes_are_clipped_to_the_image() -> None:
    out = apply_occluders(grey_image()[:, :, 0], [(-50, -50, 5, 5), (75, 55, 500, 500)])
    black = out == 0
    assert black[:5, :5].all() and black[55:, 75:].all()
    assert black.sum() == 25 + 25


def test_boxes_on_a_downscaled_photo_are_in_original_pixels() -> None:
    loaded = load_image(grey_image(600, 800), max_side=400)  # working copy at half size
    occluded = apply_occluders(loaded, [(100, 200, 300, 260)])
    assert occluded.original_size == (800, 600) and occluded.size == (400, 300)
    black = ~occluded.pixels.any(-1)
    expected = np.zeros((300, 400), bool)
    expected[100:130, 50:150] = True
    np.testing.assert_array_equal(black, expected)
    assert loaded.pixels.all()  # the input LoadedImage is unchanged


def test_invalid_boxes_raise_clear_errors() -> None:
    image = grey_image()
    with pytest.raises(ValueError, match="x1 > x0"):
        apply_occluders(image, [(30, 10, 20, 40)])
    with pytest.raises(ValueError, match="entirely outside"):
        apply_occluders(image, [(100, 10, 120, 40)])
    with pytest.raises(ValueError, match="wrap a single box"):
        apply_occluders(image, (1, 2, 3, 4))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"\(N, 4\)"):
        apply_occluders(image, [(1, 2, 3)])
    with pytest.raises(ValueError, match="finite"):
        apply_occluders(image, [(1, 2, np.nan, 4)])
    np.testing.assert_array_equal(apply_occluders(image, []), image)


def test_occluders_are_checked_once_and_read_only_then_passed_on_as_they_are() -> None:
    occluders = Occluders.of([(10, 5, 30, 25), (40, 40, 41.5, 45)])
    assert len(occluders) == 2 and occluders.boxes.dtype == np.float64
    assert Occluders.of(occluders) is occluders
    assert len(Occluders.of(None)) == 0 and len(Occluders.of([])) == 0
    with pytest.raises(ValueError):
        occluders.boxes[0, 0] = 0.0
    with pytest.raises(ValueError, match="x1 > x0"):
        Occluders.of([(30, 10, 20, 40)])
    with pytest.raises(ValueError, match="wrap a single box"):
        Occluders.of((1, 2, 3, 4))  # type: ignore[arg-type]
    points = np.array([[10.0, 5.0], [29.4, 24.4], [29.6, 10.0], [41.0, 44.0], [9.4, 6.0]])
    np.testing.assert_array_equal(occluders.covers(points), [True, True, False, True, False])
    np.testing.assert_array_equal(points_under_boxes(points, occluders.boxes),
                                  occluders.covers(points))  # fmt: skip
    painted = apply_occluders(grey_image(), occluders)
    np.testing.assert_array_equal(painted, apply_occluders(grey_image(), occluders.boxes))
    assert not painted[5:25, 10:30].any() and painted[5:25, 30].all()


@pytest.mark.parametrize(
    ("boxes", "found"),
    [
        (np.arange(12).reshape(2, 6) * 50, "(2, 6)"),  # once read as 3 boxes
        (np.arange(1, 17).reshape(2, 2, 4) * 10, "(2, 2, 4)"),  # once read as 4 boxes
        ([(1, 2, 3)], "(1, 3)"),
        (np.zeros((3, 0)), "(3, 0)"),  # empty, but not (0, 4): once read as no box
        (np.zeros((0, 5)), "(0, 5)"),
        (np.zeros((2, 0, 4)), "(2, 0, 4)"),
        ([[]], "(1, 0)"),
        ([(1, 2, 3, 4), (1, 2)], "box 1 has 2"),  # ragged: once numpy's own message
        ([(1, 2, 3, 4), [(1, 2), 3, 4, 5]], "box 1"),
    ],
)
def test_boxes_of_the_wrong_shape_are_refused_before_any_reshape(boxes, found) -> None:
    with pytest.raises(ValueError) as caught:
        Occluders.of(boxes)
    message = str(caught.value)
    assert "(N, 4)" in message and "(x0, y0, x1, y1)" in message and found in message, message


@pytest.mark.parametrize(
    "boxes",
    [
        [("a", 2, 3, 4)],
        np.array([[1 + 2j, 2, 3, 4]]),
        [(True, 2, 3, 4)],
        [(None, 2, 3, 4)],
    ],
)
def test_boxes_must_hold_real_numbers(boxes) -> None:
    with pytest.raises(ValueError, match="real numbers"):
        Occluders.of(boxes)


def test_every_empty_form_means_no_occluder() -> None:
    for empty in (None, [], (), np.zeros((0, 4)), np.zeros(0)):
        assert Occluders.of(empty).boxes.shape == (0, 4)
    integer_boxes = Occluders.of(np.array([[1, 2, 3, 4]], dtype=np.int16))
    np.testing.assert_array_equal(integer_boxes.boxes, [[1.0, 2.0, 3.0, 4.0]])

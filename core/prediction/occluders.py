"""Artificial occluders: black boxes painted over a photo before detection and edge extraction.

The paper shows how uncertainty grows when parts of the body are hidden; painting boxes over a
photo reproduces that. Box coordinates are ``(x0, y0, x1, y1)`` in original-photo pixels and
follow slicing: pixel column ``i`` spans ``[i, i + 1)`` in box coordinates, so an integer box
blacks out exactly ``image[y0:y1, x0:x1]``; a fractional box blacks out every pixel it touches.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real
from typing import TypeVar

import numpy as np

from hkpd.prediction.image_input import LoadedImage

Image = TypeVar("Image", np.ndarray, LoadedImage)

OccluderBoxes = Sequence[Sequence[float]] | np.ndarray
"""What callers may pass for occluders: ``(N, 4)`` ``(x0, y0, x1, y1)`` boxes (may be empty)."""


@dataclass(frozen=True, eq=False)
class Occluders:
    """Black boxes over a photo, "this part of the photo gives no evidence", checked once.

    Made at the API boundary (:meth:`of`) and passed on as they are: the painting
    (:func:`apply_occluders`), the evidence rule (:func:`hkpd.prediction.evidence_rule.
    evidence_mask`) and the network input all read the same boxes.

    Attributes:
        boxes: ``(N, 4)`` float64 ``(x0, y0, x1, y1)`` with ``x1 > x0`` and ``y1 > y0``, finite,
            in the pixels of the image they cover (for a photo: the original photo's);
            read-only. ``N = 0``: no occluder.

    Raises:
        ValueError: boxes not ``(N, 4)`` finite real numbers (checked before any reshape: a
            ``(2, 6)`` or ``(2, 2, 4)`` array, ``[(1, 2, 3)]``, ragged lists, bools, strings,
            complex numbers are refused, the message naming the expected shape and what was
            found), a single unwrapped box, or ``x1 <= x0`` / ``y1 <= y0``.
    """

    boxes: np.ndarray

    def __post_init__(self) -> None:
        array = _box_array(self.boxes)
        if not np.isfinite(array).all():
            raise ValueError("occluder boxes must be finite numbers")
        for x0, y0, x1, y1 in array:
            if x1 <= x0 or y1 <= y0:
                raise ValueError(f"occluder box {(x0, y0, x1, y1)} needs x1 > x0 and y1 > y0")
        array.setflags(write=False)
        object.__setattr__(self, "boxes", array)

    @classmethod
    def of(cls, boxes: Occluders | OccluderBoxes | None) -> Occluders:
        """``boxes`` as :class:`Occluders` (None: none; :class:`Occluders`: themselves)."""
        if isinstance(boxes, Occluders):
            return boxes
        return cls(np.zeros((0, 4)) if boxes is None else boxes)

    def __repr__(self) -> str:
        """One line of at most 200 characters: the count and the first boxes (pixels)."""
        shown = ", ".join(
            "(" + ", ".join(f"{value:.5g}" for value in box) + ")" for box in self.boxes[:3]
        )
        count = len(self.boxes)
        listed = (": " + shown + (", …" if count > 3 else "")) if count else ""
        return f"Occluders({count} box{'' if count == 1 else 'es'}{listed})"

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    def covers(self, points: np.ndarray) -> np.ndarray:
        """``(...)`` bool: which ``(..., 2)`` points (pixel centres at integers, in the boxes'
        pixels) lie on a pixel that :func:`apply_occluders` blacks out."""
        pixel = np.floor(np.asarray(points, dtype=np.float64) + 0.5)
        covered = np.zeros(pixel.shape[:-1], dtype=bool)
        u, v = pixel[..., 0], pixel[..., 1]
        for x0, y0, x1, y1 in self.boxes:
            covered |= (
                (u >= np.floor(x0)) & (u < np.ceil(x1)) & (v >= np.floor(y0)) & (v < np.ceil(y1))
            )
        return covered


SHAPE_NEEDED = "occluder boxes must have shape (N, 4) as (x0, y0, x1, y1) real numbers, got "
"""How every refused shape or entry type starts its message."""

SINGLE_BOX = "boxes must be a list of (x0, y0, x1, y1) boxes; wrap a single box: [box]"


def _box_array(boxes: object) -> np.ndarray:
    """``boxes`` as an ``(N, 4)`` float64 array, checked for shape and entry type before any
    reshape: an ``(N, 4)`` array of integers or floats, or a sequence of 4-number sequences;
    any empty array or sequence of shape ``(0,)`` or ``(0, 4)`` is no box.

    Raises:
        ValueError: anything else, with :data:`SHAPE_NEEDED` and what was found.
    """
    if isinstance(boxes, (list, tuple)):
        return _boxes_from_sequence(boxes)
    array = np.asarray(boxes)
    if array.dtype == object:
        return _boxes_from_sequence(array.tolist() if array.ndim else [boxes])
    if array.dtype.kind not in "iuf":
        raise ValueError(SHAPE_NEEDED + f"an array of {array.dtype}")
    if array.shape == (4,):
        raise ValueError(SINGLE_BOX)
    if array.shape == (0,):
        return np.zeros((0, 4))
    if array.ndim != 2 or array.shape[1] != 4:
        raise ValueError(SHAPE_NEEDED + str(array.shape))
    return array.astype(np.float64)


def _boxes_from_sequence(boxes: list | tuple) -> np.ndarray:
    """:func:`_box_array` of a list or tuple: each entry a sequence (or 1-D array) of 4 real
    numbers (not bools)."""
    if len(boxes) == 4 and all(_is_real(entry) for entry in boxes):
        raise ValueError(SINGLE_BOX)
    rows = []
    for index, box in enumerate(boxes):
        if isinstance(box, np.ndarray) and box.ndim == 1:
            box = box.tolist()
        if not isinstance(box, (list, tuple)):
            raise ValueError(SHAPE_NEEDED + f"box {index} is {_shown(box)}")
        rows.append(box)
    lengths = [len(row) for row in rows]
    if any(length != 4 for length in lengths):
        if len(set(lengths)) == 1:
            raise ValueError(SHAPE_NEEDED + f"({len(rows)}, {lengths[0]})")
        index = next(i for i, length in enumerate(lengths) if length != 4)
        raise ValueError(SHAPE_NEEDED + f"box {index} has {lengths[index]} numbers")
    for index, row in enumerate(rows):
        if not all(_is_real(entry) for entry in row):
            raise ValueError(SHAPE_NEEDED + f"box {index} holds {_shown(row)}")
    return np.array(rows, dtype=np.float64).reshape(len(rows), 4)


def _is_real(value: object) -> bool:
    """A real number (python or numpy), not a bool."""
    return isinstance(value, Real) and not isinstance(value, (bool, np.bool_))


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def apply_occluders(image: Image, boxes: Occluders | OccluderBoxes) -> Image:
    """A copy of ``image`` with each box painted black.

    Args:
        image: ``(H, W, C)`` or ``(H, W)`` pixel array (boxes in its own pixels), or a
            :class:`LoadedImage` (boxes in ORIGINAL-photo pixels, mapped onto its possibly
            downscaled working pixels).
        boxes: :class:`Occluders`, or ``(N, 4)`` ``(x0, y0, x1, y1)``; parts outside the image
            are clipped away. ``N = 0`` returns an unchanged copy.

    Returns:
        Same kind as ``image`` (a new array / LoadedImage; the input is not modified).

    Raises:
        ValueError: boxes that :class:`Occluders` refuses, or a box entirely outside the image
            (probably given in the wrong image's pixels).
    """
    if isinstance(image, LoadedImage):
        width, height = image.original_size
        scale = image.scale
        pixels = image.pixels
    else:
        pixels = np.asarray(image)
        if pixels.ndim not in (2, 3):
            raise ValueError(f"expected an (H, W[, C]) image, got shape {pixels.shape}")
        height, width = pixels.shape[:2]
        scale = (1.0, 1.0)
    occluders = Occluders.of(boxes)
    out = pixels.copy()
    for x0, y0, x1, y1 in occluders.boxes:
        if x1 <= 0 or y1 <= 0 or x0 >= width or y0 >= height:
            raise ValueError(
                f"occluder box {(x0, y0, x1, y1)} lies entirely outside the {width}x{height} "
                "image; give boxes in pixels of the original photo"
            )
        # Pixel-edge coordinates scale directly with the image size.
        cols = _touched(x0 * scale[0], x1 * scale[0], out.shape[1])
        rows = _touched(y0 * scale[1], y1 * scale[1], out.shape[0])
        out[rows, cols] = 0
    if isinstance(image, LoadedImage):
        return image.with_pixels(out)
    return out


def _touched(low: float, high: float, length: int) -> slice:
    """Slice of the pixels ``i`` (spanning ``[i, i + 1)``) that ``[low, high)`` overlaps."""
    start = int(np.clip(np.floor(low), 0, length))
    stop = int(np.clip(np.ceil(high), 0, length))
    return slice(start, stop)


def points_under_boxes(points: np.ndarray, boxes: Occluders | OccluderBoxes) -> np.ndarray:
    """Which points lie on a pixel that :func:`apply_occluders` blacks out for these boxes.

    Args:
        points: ``(..., 2)`` pixel coordinates (pixel centres at integers), in the boxes' pixels.
        boxes: :class:`Occluders`, or ``(N, 4)`` ``(x0, y0, x1, y1)`` (may be empty).

    Returns:
        ``(...)`` bool.
    """
    return Occluders.of(boxes).covers(points)

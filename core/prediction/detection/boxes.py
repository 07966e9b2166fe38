"""Boxes around people for the keypoint detector: checking a user's ``bbox``, the padded search
region it stands for, and the box around detected landmarks.

Coordinates are ``(u, v)`` pixels with pixel centres at integers (:mod:`hkpd.camera_conventions`);
a box ``(x0, y0, x1, y1)`` is given in original-photo pixels.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hkpd.prediction.image_input import LoadedImage

SEARCH_BOX_PADDING = 0.1
"""A ``bbox`` search region is widened by this fraction of its width/height on every side, so
that a tight box does not cut off the hands or feet the detector needs to see."""

MIN_SEARCH_REGION = 16
"""Smallest search region side, in working-image pixels, that is worth running the detector on."""


def validated_box(bbox: Sequence[float] | np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(4,)`` float64 box after checking shape, order and overlap with the photo.

    Raises:
        ValueError: not four finite numbers, ``x1 <= x0`` or ``y1 <= y0``, or outside the photo.
    """
    box = np.asarray(bbox, dtype=np.float64)
    if box.shape != (4,) or not np.isfinite(box).all():
        raise ValueError(f"bbox must be four finite numbers (x0, y0, x1, y1), got {bbox!r}")
    x0, y0, x1, y1 = box
    if x1 <= x0 or y1 <= y0:
        raise ValueError(f"bbox must have x1 > x0 and y1 > y0 (x0, y0, x1, y1), got {bbox!r}")
    width, height = image_size
    if x1 <= 0 or y1 <= 0 or x0 >= width or y0 >= height:
        raise ValueError(
            f"bbox {_shown(box)} lies outside the {width}x{height} photo; give it in pixels of "
            "the original photo as displayed (x0, y0, x1, y1)"
        )
    return box


def _shown(box: np.ndarray) -> str:
    """``(x0, y0, x1, y1)`` as the user would write it (``(0, -40.5, 1080, 0)``)."""
    return "(" + ", ".join(f"{float(v):g}" for v in box) + ")"


def search_region(loaded: LoadedImage, box: np.ndarray) -> tuple[int, int, int, int]:
    """Integer working-image slice bounds ``(x0, y0, x1, y1)`` of the padded, clipped box.

    Raises:
        ValueError: the region is smaller than :data:`MIN_SEARCH_REGION` pixels.
    """
    pad = SEARCH_BOX_PADDING * np.array([box[2] - box[0], box[3] - box[1]])
    corners = np.array([box[:2] - pad, box[2:] + pad])
    # Box corners are pixel edges; map them as edges (centre coordinates + 0.5).
    edges = loaded.from_original(corners - 0.5) + 0.5
    width, height = loaded.size
    x0, y0 = np.clip(np.floor(edges[0]), 0, [width, height]).astype(int)
    x1, y1 = np.clip(np.ceil(edges[1]), 0, [width, height]).astype(int)
    if min(x1 - x0, y1 - y0) < MIN_SEARCH_REGION:
        raise ValueError(
            f"bbox {_shown(box)} covers only {x1 - x0}x{y1 - y0} pixels of the photo; draw a "
            "box around the whole person"
        )
    return int(x0), int(y0), int(x1), int(y1)


def clipped_box(points: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Bounding box ``(x0, y0, x1, y1)`` of ``(N, 2)`` points, clipped to the photo's pixels."""
    width, height = image_size
    low = np.clip(points.min(0), -0.5, [width - 0.5, height - 0.5])
    high = np.clip(points.max(0), -0.5, [width - 0.5, height - 0.5])
    return np.concatenate([low, high])


def no_person_message(loaded: LoadedImage, search_box: np.ndarray | None) -> str:
    """What to tell the user when no person was found (in the photo or inside ``search_box``)."""
    where = "in the photo" if search_box is None else f"inside bbox {_shown(search_box)}"
    hint = (
        "pass --bbox x0,y0,x1,y1 around the person (several people, or a small person)"
        if search_box is None
        else "check the bbox covers the whole person, in pixels of the original photo"
    )
    return (
        f"{loaded.source}: no person found {where}; {hint}, or use a photo where the person is "
        "large, well lit and mostly in the frame"
    )


TILE_OVERLAP = 1.5
"""A tile of :func:`tile_bounds` is this many grid cells wide and high (neighbours overlap)."""


def tile_bounds(width: int, height: int, tiles: int) -> list[tuple[int, int, int, int]]:
    """The whole ``width × height`` image, then a ``tiles × tiles`` grid of overlapping parts.

    Each part is centred on its grid cell and :data:`TILE_OVERLAP` cells wide and high, clipped
    to the image, so that a person on a cell border lies wholly inside some part.

    Returns:
        ``(x0, y0, x1, y1)`` integer slice bounds, the whole image first (``1 + tiles²``
        entries; just the whole image for ``tiles <= 1``).
    """
    bounds = [(0, 0, width, height)]
    if tiles <= 1:
        return bounds
    cell_w, cell_h = width / tiles, height / tiles
    half_w, half_h = TILE_OVERLAP * cell_w / 2, TILE_OVERLAP * cell_h / 2
    for row in range(tiles):
        for column in range(tiles):
            u, v = (column + 0.5) * cell_w, (row + 0.5) * cell_h
            x0, x1 = max(0, round(u - half_w)), min(width, round(u + half_w))
            y0, y1 = max(0, round(v - half_h)), min(height, round(v + half_h))
            bounds.append((int(x0), int(y0), int(x1), int(y1)))
    return bounds


def box_intersection(first: np.ndarray, second: np.ndarray) -> float:
    """Area (pixels²) of the overlap of two ``(x0, y0, x1, y1)`` boxes (0 when apart)."""
    low = np.maximum(first[:2], second[:2])
    high = np.minimum(first[2:], second[2:])
    return float(np.prod(np.clip(high - low, 0, None)))


def box_iou(first: np.ndarray, second: np.ndarray) -> float:
    """Intersection over union of two ``(x0, y0, x1, y1)`` boxes (0 for empty boxes)."""
    inter = box_intersection(first, second)
    union = float(np.prod(first[2:] - first[:2]) + np.prod(second[2:] - second[:2])) - inter
    return inter / union if union > 0 else 0.0

"""Annotated real photos turned by quarter turns: the any-orientation check on real people.

The synthetic any-orientation split rolls rendered bodies to every angle; on real photos,
people who lie or hang upside down are rare in a small annotated set (``coco_mini`` has four
people leaning more than 30°). A quarter turn of a photo is exact (pixels move, none are
resampled or invented), so the same people with the same human keypoints can be scored lying
on their side (90°, 270°) and upside down (180°): the whole pipeline (detector, crop, upright
reading, network, evidence fit) sees real pixels at those orientations. The ratio of their
errors to the unturned photos' is the real-photo counterpart of the synthetic split's ratio.

Turns are clockwise on screen. A point ``(u, v)`` of a ``W x H`` photo goes to
``(H - 1 - v, u)`` (90°), ``(W - 1 - u, H - 1 - v)`` (180°) or ``(v, W - 1 - u)`` (270°), with
pixel centres at integer coordinates (:mod:`hkpd.camera_conventions`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.prediction.image_input import load_image

QUARTER_TURNS = (90, 180, 270)
"""The turns scored, degrees clockwise."""

_OPENCV_TURNS = {
    90: cv2.ROTATE_90_CLOCKWISE,
    180: cv2.ROTATE_180,
    270: cv2.ROTATE_90_COUNTERCLOCKWISE,
}

_LARGEST_SIDE = 1_000_000
"""No photo is downscaled when it is turned (the predictor downscales later, as for any)."""


def turn_points(points: np.ndarray, degrees: int, width: int, height: int) -> np.ndarray:
    """``(..., 2)`` pixels of a ``width x height`` photo, in the photo turned clockwise by
    ``degrees`` (90, 180 or 270)."""
    points = np.asarray(points, dtype=np.float64)
    u, v = points[..., 0], points[..., 1]
    if degrees == 90:
        return np.stack([height - 1 - v, u], axis=-1)
    if degrees == 180:
        return np.stack([width - 1 - u, height - 1 - v], axis=-1)
    if degrees == 270:
        return np.stack([v, width - 1 - u], axis=-1)
    raise ValueError(f"a quarter turn is 90, 180 or 270 degrees, got {degrees}")


def turned_person(person: AnnotatedPerson, degrees: int, folder: Path) -> AnnotatedPerson:
    """``person`` on their photo turned clockwise by ``degrees``, written losslessly (PNG) to
    ``folder`` (one file per photo and turn, reused when it exists).

    The photo is loaded as the predictor loads it (EXIF orientation applied), so the
    annotation's pixels and the turned copy's agree.

    Raises:
        ValueError: ``degrees`` is not a quarter turn.
        hkpd.prediction.image_input.ImageInputError: the photo cannot be read.
    """
    if degrees not in _OPENCV_TURNS:
        raise ValueError(f"a quarter turn is 90, 180 or 270 degrees, got {degrees}")
    loaded = load_image(person.image_path, max_side=_LARGEST_SIDE)
    width, height = loaded.size
    path = Path(folder) / f"{person.image_path.parent.name}_{person.image_path.stem}_{degrees}.png"
    if not path.is_file():
        Image.fromarray(cv2.rotate(loaded.pixels, _OPENCV_TURNS[degrees])).save(path)
    corners = turn_points(person.bbox.reshape(2, 2), degrees, width, height)
    size = (height, width) if degrees in (90, 270) else (width, height)
    return replace(
        person,
        image_path=path,
        bbox=np.concatenate([corners.min(0), corners.max(0)]),
        keypoints=turn_points(person.keypoints, degrees, width, height),
        outlines=tuple(turn_points(outline, degrees, width, height) for outline in person.outlines),
        image_size=size,
    )

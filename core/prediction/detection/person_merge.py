"""Which person box each keypoint detection is, so that nobody is listed twice.

:meth:`~hkpd.prediction.detection.keypoint_detector.KeypointDetector.detect_all` gathers
BlazePose's detections (its face-and-torso detector on the whole photo and a grid) and
NanoDet's whole-person boxes (:mod:`~hkpd.prediction.detection.person_detector`). Each box is
one person, so:

- :func:`box_owners`: each box is *owned* by at most one detection and each detection owns at
  most one box: a detection read in a box owns it; the others are paired one to one, the
  best-overlapping pairs first, at IoU >= :data:`OWNER_IOU`, or at IoU >= :data:`HELD_IOU`
  when the box lies inside the detection's landmark box (a person whose outstretched arms
  NanoDet's box leaves out);
- :func:`unowned_boxes`: the boxes no detection owns are people BlazePose's detector missed,
  to be read in their box; :func:`read_fits_box`: whether such a read is the box's person
  (its confident keypoints inside the box, however far its guessed hidden limbs reach);
- :func:`kept_people`: a detection owning no box that lies mostly (:data:`INSIDE_OWNED`)
  inside a box another detection owns is that person read again (e.g. a catcher's upper body
  inside his own box) and is dropped; a person inside another's box who has a box of their own
  (a child in front of an adult) owns it and is kept, and so is a detection lying in no owned
  box (a person NanoDet missed).

Boxes are ``(x0, y0, x1, y1)`` pixels of one photo.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hkpd.prediction.detection.boxes import box_intersection, box_iou

__all__ = [
    "BOX_MARGIN",
    "HELD_IOU",
    "INSIDE_OWNED",
    "KEYPOINTS_INSIDE",
    "OWNER_IOU",
    "box_owners",
    "inside_fraction",
    "kept_people",
    "read_fits_box",
    "unowned_boxes",
]

OWNER_IOU = 0.4
"""A detection's landmark box overlapping a person box this much (IoU) can own it (a landmark
box covers the 33 landmarks, NanoDet's box also hair, hands and feet: the same person's two
boxes overlap by about 0.6-0.8)."""

HELD_IOU = 0.2
"""A detection whose landmark box holds a person box (:data:`INSIDE_OWNED` of the box's area
inside it) can own that box from this IoU on."""

INSIDE_OWNED = 0.8
"""A detection owning no box with this fraction of its landmark box's area inside a box owned
by another detection is that person found twice."""

KEYPOINTS_INSIDE = 0.8
"""A detection read in a person box is that box's person when this fraction of its confident
keypoints lie inside the box (grown by :data:`BOX_MARGIN`)."""

BOX_MARGIN = 0.1
"""Each side of a person box is moved out by this fraction of its width or height when
counting the keypoints inside it."""


def inside_fraction(inner: np.ndarray, outer: np.ndarray) -> float:
    """The fraction of ``inner``'s area that lies inside ``outer`` (0 for an empty ``inner``)."""
    area = float(np.prod(np.clip(inner[2:] - inner[:2], 0, None)))
    if area <= 0:
        return 0.0
    return box_intersection(inner, outer) / area


def read_fits_box(keypoints: np.ndarray, confident: np.ndarray, box: np.ndarray) -> bool:
    """Whether a detection read in ``box`` is the box's person: at least
    :data:`KEYPOINTS_INSIDE` of its confident keypoints inside the box grown by
    :data:`BOX_MARGIN` (and at least one confident keypoint).

    Args:
        keypoints: ``(17, 2)`` pixels.
        confident: ``(17,)`` bool, the keypoints that count.
        box: ``(x0, y0, x1, y1)`` pixels.
    """
    confident = np.asarray(confident, bool)
    if not confident.any():
        return False
    box = np.asarray(box, np.float64)
    margin = BOX_MARGIN * np.tile(box[2:] - box[:2], 2) * np.array([-1.0, -1.0, 1.0, 1.0])
    low, high = (box + margin)[:2], (box + margin)[2:]
    points = np.asarray(keypoints, np.float64)[confident]
    inside = np.all((points >= low) & (points <= high), axis=1)
    return float(inside.mean()) >= KEYPOINTS_INSIDE


def box_owners(
    landmark_boxes: Sequence[np.ndarray],
    person_boxes: Sequence[np.ndarray],
    read_in: Sequence[int | None] | None = None,
) -> list[int | None]:
    """For each detection (its landmark box), the index of the person box it owns, or None.

    Args:
        landmark_boxes: each detection's landmark box.
        person_boxes: the person detector's boxes.
        read_in: for each detection, the index of the box it was read in (it owns that box),
            or None (default: no detection was read in a box).

    The other detections and boxes are paired one to one by decreasing IoU, each at most once,
    pairs below :data:`OWNER_IOU` only when the detection's landmark box holds the person box
    and their IoU reaches :data:`HELD_IOU`.
    """
    owners = [None] * len(landmark_boxes) if read_in is None else list(read_in)
    taken = {j for j in owners if j is not None}
    pairs = sorted(
        (
            (box_iou(np.asarray(mine, np.float64), np.asarray(box, np.float64)), i, j)
            for i, mine in enumerate(landmark_boxes)
            for j, box in enumerate(person_boxes)
        ),
        key=lambda pair: (-pair[0], pair[1], pair[2]),
    )
    for iou, i, j in pairs:
        if iou < OWNER_IOU and (iou < HELD_IOU or not _holds(landmark_boxes[i], person_boxes[j])):
            continue
        if owners[i] is None and j not in taken:
            owners[i] = j
            taken.add(j)
    return owners


def _holds(landmark_box: np.ndarray, person_box: np.ndarray) -> bool:
    """Whether :data:`INSIDE_OWNED` of ``person_box``'s area lies inside ``landmark_box``."""
    inner, outer = np.asarray(person_box, np.float64), np.asarray(landmark_box, np.float64)
    return inside_fraction(inner, outer) >= INSIDE_OWNED


def unowned_boxes(
    landmark_boxes: Sequence[np.ndarray], person_boxes: Sequence[np.ndarray]
) -> list[int]:
    """Indices of the person boxes no detection owns (:func:`box_owners`), in their order."""
    owned = set(box_owners(landmark_boxes, person_boxes))
    return [j for j in range(len(person_boxes)) if j not in owned]


def kept_people(
    landmark_boxes: Sequence[np.ndarray],
    person_boxes: Sequence[np.ndarray],
    read_in: Sequence[int | None] | None = None,
) -> list[int]:
    """Indices of the detections to list, in their order: those owning a person box
    (:func:`box_owners`, ``read_in`` as there), and those owning none whose landmark box lies
    less than :data:`INSIDE_OWNED` inside every box owned by another detection."""
    owners = box_owners(landmark_boxes, person_boxes, read_in)
    owned = [np.asarray(person_boxes[j], np.float64) for j in owners if j is not None]
    kept = []
    for i, (mine, owner) in enumerate(zip(landmark_boxes, owners, strict=True)):
        box = np.asarray(mine, np.float64)
        if owner is not None or all(inside_fraction(box, other) < INSIDE_OWNED for other in owned):
            kept.append(i)
    return kept

"""The Person menu's words: where each person found stands in the photo, which of them the
explorer shows first, and what to do when nobody is found in a picked box.

Pure functions of boxes ``(x0, y0, x1, y1)`` in photo pixels (no viser), so the app and its
tests share them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hkpd.explorer.state import clamp_box
from hkpd.prediction.detection.boxes import box_iou

Box = tuple[float, float, float, float]

EDGE_SHARE = 0.01
"""A person's box within this share of the photo's larger side of an edge is cut off by it
(the quality flag ``cut_off_by_edge``'s margin, :data:`hkpd.prediction.quality.EDGE_FRACTION`)."""

SAME_PERSON_IOU = 0.3
"""A reading's person box overlapping a listed person's box this much is that person."""

SMALL_SHARE, LARGE_SHARE = 0.35, 0.7
"""A person whose box area is below / at least this share of the largest one's is "small" /
"large" (else "medium")."""


def cut_off(box: Box, image_size: tuple[int, int]) -> bool:
    """``box`` reaches the photo's edge (:data:`EDGE_SHARE`): part of the person may be out."""
    width, height = image_size
    margin = EDGE_SHARE * max(width, height)
    x0, y0, x1, y1 = box
    return min(x0, y0, width - x1, height - y1) < margin


def person_places(people: Sequence[Box], image_size: tuple[int, int]) -> tuple[str, ...]:
    """Where each listed person is, in words: ``"left, small"``, ``"centre, large, cut off
    by the edge"`` (the third of the photo's width their box's centre is in, and their size
    against the largest person's)."""
    areas = [max(b[2] - b[0], 0.0) * max(b[3] - b[1], 0.0) for b in people]
    largest = max(areas, default=0.0) or 1.0
    width = image_size[0]
    places = []
    for box, area in zip(people, areas, strict=True):
        centre = (box[0] + box[2]) / 2
        side = "left" if centre < width / 3 else "right" if centre > 2 * width / 3 else "centre"
        share = area / largest
        size = "small" if share < SMALL_SHARE else "large" if share >= LARGE_SHARE else "medium"
        edge = ", cut off by the edge" if cut_off(box, image_size) else ""
        places.append(f"{side}, {size}{edge}")
    return tuple(places)


def read_person(people: Sequence[Box], reading_box: Box | None) -> int | None:
    """The listed person a reading made without a person box is of: the one whose box overlaps
    the reading's person box most (at least :data:`SAME_PERSON_IOU`), or None."""
    if reading_box is None or not people:
        return None
    overlaps = [box_iou(np.asarray(reading_box), np.asarray(box)) for box in people]
    best = int(np.argmax(overlaps))
    return best if overlaps[best] >= SAME_PERSON_IOU else None


def person_to_show(
    people: Sequence[Box], reading_box: Box | None, image_size: tuple[int, int]
) -> int | None:
    """Whom to show of several listed people when the first reading was made without a box
    (the detector's own pick): None to keep that reading, else the listed person to predict in
    their box. A pick cut off by the photo's edge gives way to the largest whole person; any
    other pick is predicted in its listed box, so that the explorer reads each listed person
    exactly as ``hkpd-predict --all-people`` and ``Predictor.predict_all`` do (the same box:
    the same reading, the same quality flags)."""
    if len(people) < 2:
        return None
    whole = [i for i, box in enumerate(people) if not cut_off(box, image_size)]
    picked = read_person(people, reading_box)
    if picked is None:  # a provider that does not say whom it read: keep its reading
        return None
    if cut_off(people[picked], image_size) and whole:
        return whole[0]
    return picked


def no_person_advice(person_box: Box | None) -> str:
    """What the status line says when nobody is found: without a box, how to pick the person;
    in a picked box, what to do instead (never "pick the person" again, which found nobody).
    The detector misses a person who fills little of the box it looks in (the shipped photo's
    person shrunk to 45 px tall: found in a box 3 px around them, missed in one 40 px around
    them), so a tighter box is the first thing to try."""
    if person_box is None:
        return (
            "No person was found. Click **Pick the person**, then drag a box around them on "
            "the photo."
        )
    x0, y0, x1, y1 = person_box
    return (
        f"No person was found in your box ({x1 - x0:.0f} × {y1 - y0:.0f} px). The detector "
        "misses a person who fills little of the box: drag a tighter box just around them, "
        "head to feet (or load a larger photo of them). **Forget the person box** goes back "
        "to the person found without one."
    )


def menu_entries(
    people: Sequence[Box],
    person_box: Box | None,
    reading_box: Box | None,
    image_size: tuple[int, int],
) -> tuple[int | None, tuple[str, ...]]:
    """The Person menu's choice and each person's place (:func:`person_places`).

    Args:
        people: the listed people's boxes (photo pixels, as found).
        person_box: the state's person box (whole pixels, clipped), or None.
        reading_box: the shown reading's person box, or None (unknown, or nobody shown).
        image_size: ``(width, height)``.

    Returns:
        The 0-based person shown (the listed box equal to ``person_box``; without a box the
        one the reading is of, else 0), or None when ``person_box`` is a box the user picked.
    """
    listed = [clamp_box(person, *image_size) for person in people]
    if person_box is None:
        found = read_person(people, reading_box)
        choice: int | None = 0 if found is None else found
    else:
        choice = listed.index(person_box) if person_box in listed else None
    return choice, person_places(people, image_size)

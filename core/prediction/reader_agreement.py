"""How far BlazePose and the second reader (MoveNet Thunder) agree on one person (issue 59).

Both readers give COCO-17 keypoints in photo pixels. :func:`reader_agreement` compares them:

- per keypoint, the distance between the two readings as a share of the person's size;
- the **left/right swap test**: how much closer the second reader comes to BlazePose when its
  left and right labels are traded (positive: the two disagree on which side is which);
- the **whole person**: how far apart the two torsos are (shoulders and hips' centres; large
  when the readers found different people).

These are the quality score's reader signals (:mod:`hkpd.prediction.quality`) and tell the fit
which keypoints to trust (:mod:`hkpd.prediction.second_evidence`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hkpd.coco_keypoints import COCO17_MIRROR_ORDER

TORSO = (5, 6, 11, 12)
"""COCO indices of the shoulders and hips (the torso's centre)."""

DISAGREE_FRACTION = 0.15
"""A keypoint on which the readers lie further apart than this share of the person's size is
disputed."""

DISTANCE_FLOOR = 1e-3
"""Distances (shares of the person's size) are floored here before their log10."""


@dataclass(frozen=True)
class ReaderAgreement:
    """How far two readings of one person agree.

    Attributes:
        distances: ``(17,)`` distance between the two readers' keypoints / the person's size.
        mean_distance: their mean over the 17 (clipped to 1 each).
        disputed_share: share of the 17 further apart than :data:`DISAGREE_FRACTION`.
        swap_gain: mean distance as labelled minus with the second reader's left and right
            traded, / the person's size (positive: the sides are in doubt).
        torso_offset: distance between the two readers' torso centres / the person's size.
    """

    distances: np.ndarray
    mean_distance: float
    disputed_share: float
    swap_gain: float
    torso_offset: float

    @property
    def disputed(self) -> np.ndarray:
        """``(17,)`` bool: the keypoints the readers place further apart than
        :data:`DISAGREE_FRACTION` of the person's size."""
        return self.distances > DISAGREE_FRACTION

    def signals(self) -> dict[str, float]:
        """The quality signals: ``log10_readers_distance``, ``readers_disputed_share``,
        ``readers_swap_gain``, ``readers_torso_offset``."""
        return {
            "log10_readers_distance": math.log10(max(self.mean_distance, DISTANCE_FLOOR)),
            "readers_disputed_share": self.disputed_share,
            "readers_swap_gain": self.swap_gain,
            "readers_torso_offset": self.torso_offset,
        }


def person_size(person_box: np.ndarray) -> float:
    """The longer side of ``(4,)`` ``(x0, y0, x1, y1)`` box, pixels (at least 1)."""
    box = np.asarray(person_box, np.float64)
    return max(float((box[2:] - box[:2]).max()), 1.0)


def reader_agreement(first: np.ndarray, second: np.ndarray, size: float) -> ReaderAgreement:
    """Compare ``(17, 2)`` keypoints of the first reader with ``(17, 2)`` of the second (same
    pixels) on a person ``size`` pixels tall (the module docstring)."""
    first = np.asarray(first, np.float64)
    second = np.asarray(second, np.float64)
    size = max(float(size), 1.0)
    distances = np.linalg.norm(first - second, axis=-1) / size
    swapped = np.linalg.norm(first - second[list(COCO17_MIRROR_ORDER)], axis=-1) / size
    sided = np.asarray(COCO17_MIRROR_ORDER) != np.arange(17)
    clipped = np.minimum(distances, 1.0)
    torso = list(TORSO)
    offset = np.linalg.norm(first[torso].mean(0) - second[torso].mean(0)) / size
    return ReaderAgreement(
        distances=distances,
        mean_distance=float(clipped.mean()),
        disputed_share=float((distances > DISAGREE_FRACTION).mean()),
        swap_gain=float(
            np.minimum(distances[sided], 1.0).mean() - np.minimum(swapped[sided], 1.0).mean()
        ),
        torso_offset=float(min(offset, 1.0)),
    )


READER_SIGNAL_NAMES: tuple[str, ...] = (
    "log10_readers_distance",
    "readers_disputed_share",
    "readers_swap_gain",
    "readers_torso_offset",
)
"""The quality signals :meth:`ReaderAgreement.signals` gives, in this order."""


def detection_agreement(detection: object) -> ReaderAgreement | None:
    """The agreement of a :class:`~hkpd.prediction.detection.keypoint_detector.KeypointDetection`
    with its ``second_reading`` (the person's size: the longer side of its ``person_box``);
    None when the second reader did not read it."""
    second = getattr(detection, "second_reading", None)
    if second is None:
        return None
    size = person_size(detection.person_box)
    return reader_agreement(detection.keypoints, second.keypoints, size)


def second_reading_summary(detection: object) -> dict[str, object] | None:
    """What ``summary.json`` says of the second reader (``keypoints.second_reader``): its
    keypoints (original-photo pixels) and scores, the distances from BlazePose's as shares of
    the person's size and the keypoints disputed, the swap gain and the torso offset; None when
    it did not read the person."""
    agreement = detection_agreement(detection)
    if agreement is None:
        return None
    second = detection.second_reading
    return {
        "reader": "MoveNet SinglePose Thunder",
        "keypoints": np.round(np.asarray(second.keypoints, np.float64), 2).tolist(),
        "scores": np.round(np.asarray(second.scores, np.float64), 4).tolist(),
        "distances": np.round(agreement.distances, 4).tolist(),
        "disputed": [int(k) for k in np.flatnonzero(agreement.disputed)],
        "swap_gain": round(agreement.swap_gain, 4),
        "torso_offset": round(agreement.torso_offset, 4),
    }


def second_reader_outline(detection: object) -> dict[str, np.ndarray]:
    """The overview's second-reader fields (``Outlines.second_keypoints``,
    ``second_disputed``: the second reader's keypoints, the disputed ones those it is confident
    of, score >= 0.3); empty when it did not read the person."""
    agreement = detection_agreement(detection)
    if agreement is None:
        return {}
    second = detection.second_reading
    confident = np.asarray(second.scores, np.float64) >= 0.3
    return {
        "second_keypoints": np.asarray(second.keypoints, np.float64),
        "second_disputed": agreement.disputed & confident,
    }

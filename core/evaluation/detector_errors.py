"""How BlazePose's keypoints differ from human annotations: the numbers behind the detector-like
noise of :mod:`hkpd.synthesis.detector_noise` and of training (``--keypoint-noise-sigma``).

For each annotated person the detector runs inside the person's (widened) box, like
:func:`hkpd.evaluation.real_photos.evaluate_photos`. Per COCO keypoint that the annotators marked
visible: a *miss* (confidence below 0.6), a *left/right swap* (the detection is nearer the
other side's annotation than its own by a margin), an *outlier* (further than 20 % of the
person's size), and otherwise the error, in fractions of the person's size (the annotated box's
larger side). Use a split you do not report results on (e.g. coco_mini's train2017).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS, COCO17_NAMES
from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.image_input import ImageInputError

CONFIDENCE = 0.6
OUTLIER_FRACTION = 0.2
SWAP_MARGIN = 0.5
"""A swap: the distance to the other side's annotation is below this share of the distance to
the keypoint's own."""


@dataclass(frozen=True)
class DetectorErrors:
    """Summary over people (fractions of person size; rates over visible keypoints).

    Attributes:
        per_keypoint_median: ``{name: median error}`` of inlier keypoints.
        sigma: robust per-coordinate standard deviation of inliers (1.4826 × MAD of the
            coordinate errors), all keypoints pooled.
        miss_rate, swap_rate, outlier_rate: shares of visible keypoints.
        people: people evaluated; keypoints: visible keypoints scored.
    """

    per_keypoint_median: dict[str, float]
    sigma: float
    miss_rate: float
    swap_rate: float
    outlier_rate: float
    people: int
    keypoints: int


def _other_side() -> dict[int, int]:
    pairs = {}
    for left, right in COCO17_LEFT_RIGHT_PAIRS:
        pairs[left], pairs[right] = right, left
    return pairs


def detector_errors(detector, people: Sequence[AnnotatedPerson]) -> DetectorErrors:
    """Run ``detector`` (a :class:`hkpd.prediction.KeypointDetector`) on ``people``."""
    other = _other_side()
    residuals: list[np.ndarray] = []
    per_keypoint: dict[int, list[float]] = {k: [] for k in range(17)}
    counts = {"miss": 0, "swap": 0, "outlier": 0, "visible": 0}
    evaluated = 0
    for person in people:
        size = float((person.bbox[2:] - person.bbox[:2]).max())
        margin = 0.15 * size
        search = person.bbox + np.array([-margin, -margin, margin, margin])
        try:
            detection = detector.detect(str(person.image_path), bbox=search)
        except (NoPersonFoundError, ImageInputError, ValueError):
            continue
        evaluated += 1
        for k in np.flatnonzero(person.visible):
            counts["visible"] += 1
            if detection.confidences[k] < CONFIDENCE:
                counts["miss"] += 1
                continue
            offset = (detection.keypoints[k] - person.keypoints[k]) / size
            error = float(np.hypot(*offset))
            partner = other.get(int(k))
            if partner is not None and person.visible[partner]:
                to_partner = np.hypot(*(detection.keypoints[k] - person.keypoints[partner])) / size
                if to_partner < SWAP_MARGIN * error:
                    counts["swap"] += 1
                    continue
            if error > OUTLIER_FRACTION:
                counts["outlier"] += 1
                continue
            residuals.append(offset)
            per_keypoint[int(k)].append(error)
    visible = max(counts["visible"], 1)
    pooled = np.concatenate(residuals) if residuals else np.zeros(1)
    sigma = 1.4826 * float(np.median(np.abs(pooled - np.median(pooled))))
    return DetectorErrors(
        per_keypoint_median={
            COCO17_NAMES[k]: float(np.median(v)) if v else float("nan")
            for k, v in per_keypoint.items()
        },
        sigma=sigma,
        miss_rate=counts["miss"] / visible,
        swap_rate=counts["swap"] / visible,
        outlier_rate=counts["outlier"] / visible,
        people=evaluated,
        keypoints=counts["visible"],
    )

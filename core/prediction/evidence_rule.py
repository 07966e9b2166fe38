"""Which detected keypoints count as evidence: confident ones that no occluder covers.

One rule for :class:`hkpd.prediction.Predictor`, ``hkpd-predict --occluder`` and the explorer.
The detector runs on the *unpainted* photo; an occluder means "this part of the photo gives no
evidence", so a keypoint under one is dropped whatever the detector's confidence (on a painted
photo BlazePose can put a confident knee just outside the box, which must not count either:
that cannot happen here, since the painted photo is never shown to the detector). The same set
feeds the network's heatmaps, while its edge channel sees the painted photo.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hkpd.prediction.occluders import points_under_boxes
from hkpd.proxy import CONFIDENCE_THRESHOLD

EVIDENCE_CONFIDENCE = CONFIDENCE_THRESHOLD
"""Detector confidence from which a keypoint is evidence (the proxy heatmaps' 0.6)."""


def evidence_mask(
    keypoints_photo: np.ndarray,
    confidences: np.ndarray,
    occluders: Sequence[Sequence[float]] | np.ndarray = (),
    min_confidence: float = EVIDENCE_CONFIDENCE,
) -> np.ndarray:
    """``(17,)`` bool: confidence ``>= min_confidence``, finite, and on no occluded pixel.

    Args:
        keypoints_photo: ``(17, 2)`` detected keypoints, original-photo pixels.
        confidences: ``(17,)`` detector confidences.
        occluders: ``(N, 4)`` boxes ``(x0, y0, x1, y1)``, original-photo pixels (may be empty).
        min_confidence: the threshold.
    """
    points = np.asarray(keypoints_photo, dtype=np.float64)
    conf = np.asarray(confidences, dtype=np.float64)
    finite = np.isfinite(points).all(-1) & np.isfinite(conf)
    covered = points_under_boxes(np.nan_to_num(points), occluders)
    return finite & (np.nan_to_num(conf) >= min_confidence) & ~covered

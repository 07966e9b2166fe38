"""Which detected keypoints count as evidence: confident ones that no occluder covers.

One rule for :class:`hkpd.prediction.Predictor` (``predict(occluders=...)``), and so for the
explorer's occluders, whose boxes reach the predictor as they are. The detector runs on the
*unpainted* photo; an occluder means "this part of the photo gives no evidence", so a keypoint
under one is dropped whatever the detector's confidence (on a painted photo BlazePose can put a
confident knee just outside the box, which must not count either: that cannot happen here,
since the painted photo is never shown to the detector). The same set feeds the network's
heatmaps, while its edge channel sees the painted photo.
"""

from __future__ import annotations

import numpy as np

from hkpd.prediction.occluders import Occluders
from hkpd.proxy import CONFIDENCE_THRESHOLD

EVIDENCE_CONFIDENCE = CONFIDENCE_THRESHOLD
"""Detector confidence from which a keypoint is evidence: 0.6, the proxy heatmaps' threshold
(:data:`hkpd.proxy.CONFIDENCE_THRESHOLD`), so that the keypoints the network sees drawn and
the keypoints the fit is conditioned on are one set. This is the threshold the predictor reads;
the fit itself (:mod:`hkpd.conditioning`) takes the resulting mask and has no threshold."""

NO_OCCLUDERS = Occluders(np.zeros((0, 4)))
"""No occluder: every confident keypoint is evidence."""


def evidence_mask(
    keypoints_photo: np.ndarray,
    confidences: np.ndarray,
    occluders: Occluders = NO_OCCLUDERS,
    min_confidence: float = EVIDENCE_CONFIDENCE,
) -> np.ndarray:
    """``(17,)`` bool: confidence ``>= min_confidence``, finite, and on no occluded pixel.

    Args:
        keypoints_photo: ``(17, 2)`` detected keypoints, original-photo pixels.
        confidences: ``(17,)`` detector confidences.
        occluders: the boxes, original-photo pixels (may be none).
        min_confidence: the threshold.
    """
    points = np.asarray(keypoints_photo, dtype=np.float64)
    conf = np.asarray(confidences, dtype=np.float64)
    finite = np.isfinite(points).all(-1) & np.isfinite(conf)
    covered = occluders.covers(np.nan_to_num(points))
    return finite & (np.nan_to_num(conf) >= min_confidence) & ~covered

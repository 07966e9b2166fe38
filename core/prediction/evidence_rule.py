"""Which detected keypoints count as evidence: confident ones, inside the photo and the person's
box, that no occluder covers.

One rule for :class:`hkpd.prediction.Predictor` (``predict(occluders=...)``), and so for the
explorer's occluders, whose boxes reach the predictor as they are. The detector runs on the
*unpainted* photo; an occluder means "this part of the photo gives no evidence", so a keypoint
under one is dropped whatever the detector's confidence (on a painted photo BlazePose can put a
confident knee just outside the box, which must not count either: that cannot happen here,
since the painted photo is never shown to the detector). The same set feeds the network's
heatmaps, while its edge channel sees the painted photo.

BlazePose places limbs it cannot see outside the photo, and in a user's box too thin for a
person it can place a whole pose outside the photo; such points are guesses, not evidence: only
keypoints inside the photo and inside the box the detector searched
(:func:`evidence_frame`) count.
"""

from __future__ import annotations

import numpy as np

from hkpd.prediction.detection.boxes import SEARCH_BOX_PADDING
from hkpd.prediction.occluders import Occluders
from hkpd.proxy import CONFIDENCE_THRESHOLD

EVIDENCE_CONFIDENCE = CONFIDENCE_THRESHOLD
"""Detector confidence from which a keypoint is evidence: 0.6, the proxy heatmaps' threshold
(:data:`hkpd.proxy.CONFIDENCE_THRESHOLD`), so that the keypoints the network sees drawn and
the keypoints the fit is conditioned on are one set. This is the threshold the predictor reads;
the fit itself (:mod:`hkpd.conditioning`) takes the resulting mask and has no threshold."""

NO_OCCLUDERS = Occluders(np.zeros((0, 4)))
"""No occluder: every confident keypoint is evidence."""


def evidence_frame(image_size: tuple[int, int], search_box: np.ndarray | None = None) -> np.ndarray:
    """``(4,)`` ``(x0, y0, x1, y1)`` original-photo pixel edges a keypoint must lie inside to be
    evidence: the photo (``(-0.5, -0.5, W - 0.5, H - 0.5)``, pixel centres at integers), cut to
    the region the detector searched when it looked inside ``search_box`` (the box widened by
    :data:`~hkpd.prediction.detection.boxes.SEARCH_BOX_PADDING` on every side)."""
    width, height = image_size
    frame = np.array([-0.5, -0.5, width - 0.5, height - 0.5])
    if search_box is None:
        return frame
    box = np.asarray(search_box, dtype=np.float64)
    pad = SEARCH_BOX_PADDING * np.tile(box[2:] - box[:2], 2) * np.array([-1, -1, 1, 1])
    padded = box + pad
    return np.concatenate([np.maximum(frame[:2], padded[:2]), np.minimum(frame[2:], padded[2:])])


def evidence_mask(
    keypoints_photo: np.ndarray,
    confidences: np.ndarray,
    occluders: Occluders = NO_OCCLUDERS,
    min_confidence: float = EVIDENCE_CONFIDENCE,
    frame: np.ndarray | None = None,
) -> np.ndarray:
    """``(17,)`` bool: confidence ``>= min_confidence``, finite, inside ``frame`` and on no
    occluded pixel.

    Args:
        keypoints_photo: ``(17, 2)`` detected keypoints, original-photo pixels.
        confidences: ``(17,)`` detector confidences.
        occluders: the boxes, original-photo pixels (may be none).
        min_confidence: the threshold.
        frame: ``(x0, y0, x1, y1)`` the keypoints must lie in (:func:`evidence_frame`: the
            photo, or the searched box on it); None: anywhere.
    """
    points = np.asarray(keypoints_photo, dtype=np.float64)
    conf = np.asarray(confidences, dtype=np.float64)
    finite = np.isfinite(points).all(-1) & np.isfinite(conf)
    covered = occluders.covers(np.nan_to_num(points))
    inside = np.ones(len(points), dtype=bool)
    if frame is not None:
        low, high = np.asarray(frame[:2]), np.asarray(frame[2:])
        inside = ((points >= low) & (points <= high)).all(-1)
    return finite & (np.nan_to_num(conf) >= min_confidence) & ~covered & inside

"""The two keypoint readers as one observation for the fit (issue 59, "agreement as evidence").

BlazePose's keypoints are the fit's evidence (:class:`hkpd.conditioning.KeypointEvidence`).
With the second reader's reading of the same person
(:attr:`~hkpd.prediction.detection.keypoint_detector.KeypointDetection.second_reading`, MoveNet
Thunder), :func:`combined_keypoint_evidence` makes one observation of the two, per keypoint:

- **agreed** (the readers within :data:`~hkpd.prediction.reader_agreement.DISAGREE_FRACTION` of
  the person's size, Thunder's score >= :data:`MIN_SECOND_SCORE`): the two readings' weighted
  mean, each weighted by the inverse of its measured noise (:data:`SECOND_READER_WEIGHT`), so
  the mode can come closer than either reader;
- **disputed** (further apart, Thunder confident): no evidence: the fit does not pick one
  reader's limb, the network's reading of the photo decides and the posterior stays wide there;
- Thunder unsure (score below :data:`MIN_SECOND_SCORE`): BlazePose's keypoint as it was.

A disputed wrist or ankle takes BlazePose's hand or foot landmarks on that side out of the
evidence too (:func:`landmark_evidence`): they come from the same reader's reading of that
limb, and kept they would pin the limb the keypoint no longer does.

When the readers disagree on most of the body (:data:`WHOLE_BODY_DISPUTE`: they likely read
different people or one is lost) the observation is BlazePose's alone and the quality score
warns (``readers_disagree``). Occluders and the evidence rule act first: a keypoint that was not
evidence stays so.
"""

from __future__ import annotations

import numpy as np

from hkpd.prediction.network_input import NetworkInput
from hkpd.prediction.reader_agreement import detection_agreement

MIN_SECOND_SCORE = 0.3
"""Thunder's keypoint score from which its keypoint counts (Google's own demos draw >= 0.3)."""

SECOND_READER_WEIGHT = 0.6
"""Thunder's share of an agreed keypoint (BlazePose's: the rest), from the readers' measured
noise on agreed, visible keypoints (RMS error / person size: coco_mini train2017 BlazePose
0.036, Thunder 0.027, inverse-variance share 0.64; seed-1 hard synthetic photos 0.136 and 0.139,
0.49). At 0.6 the agreed keypoints' mean lies closer to the truth than either reader's (median
error per reading: train2017 0.036 vs BlazePose's 0.042, synthetic 0.028 vs 0.030;
``docs/experiments/second_reader_eval.py``)."""

DROP_DISPUTED = True
"""Disputed keypoints (Thunder confident) are no evidence (False: BlazePose's keypoint is kept,
for the experiment that weighs the choice, ``docs/experiments/second_evidence_eval.py``)."""

WHOLE_BODY_DISPUTE = 0.5
"""With more than this share of the 17 keypoints disputed, BlazePose's keypoints are kept as
they are (the readers read different people, or one is lost: the quality score warns)."""


LANDMARK_KEYPOINT = (9, 10, 9, 10, 9, 10, 15, 16, 15, 16)
"""The COCO keypoint (wrist or ankle) each BlazePose hand and foot landmark hangs from, in
:data:`hkpd.body.extremity_landmarks.BLAZEPOSE_EXTREMITY_NAMES` order (left/right pinky, index,
thumb, heel, foot index)."""


def disputed_keypoints(prepared: NetworkInput) -> np.ndarray:
    """``(17,)`` bool: the keypoints :func:`combined_keypoint_evidence` takes out of the
    evidence (disputed, Thunder confident; none without a second reading or when most of the
    body is disputed)."""
    agreement = detection_agreement(prepared.detection)
    if agreement is None or agreement.disputed_share > WHOLE_BODY_DISPUTE or not DROP_DISPUTED:
        return np.zeros(17, bool)
    confident = np.asarray(prepared.detection.second_reading.scores) >= MIN_SECOND_SCORE
    return agreement.disputed & confident


def landmark_evidence(prepared: NetworkInput) -> np.ndarray | None:
    """``(10,)`` bool: ``prepared.extremity_evidence`` less the hand and foot landmarks whose
    wrist or ankle the readers dispute (None when the detection has no landmarks)."""
    shown = prepared.extremity_evidence
    if shown is None:
        return None
    dropped = disputed_keypoints(prepared)[list(LANDMARK_KEYPOINT)]
    return np.asarray(shown, bool) & ~dropped


def combined_keypoint_evidence(prepared: NetworkInput) -> tuple[np.ndarray, np.ndarray]:
    """The fit's observation of ``prepared`` (module docstring).

    Returns:
        ``(17, 2)`` float64 keypoints in crop pixels and ``(17,)`` bool evidence; BlazePose's
        own (``prepared.keypoints_crop``, ``prepared.evidence``) when the second reader did not
        read the person.
    """
    keypoints = np.asarray(prepared.keypoints_crop, np.float64)
    evidence = np.asarray(prepared.evidence, bool)
    detection = prepared.detection
    agreement = detection_agreement(detection)
    if agreement is None or agreement.disputed_share > WHOLE_BODY_DISPUTE:
        return keypoints, evidence
    second = detection.second_reading
    confident = np.asarray(second.scores) >= MIN_SECOND_SCORE
    second_crop = np.asarray(prepared.crop.image_to_crop(second.keypoints), np.float64)
    agreed = confident & ~agreement.disputed
    mean = (1 - SECOND_READER_WEIGHT) * keypoints + SECOND_READER_WEIGHT * second_crop
    combined = np.where(agreed[:, None], mean, keypoints)
    return combined, evidence & ~disputed_keypoints(prepared)

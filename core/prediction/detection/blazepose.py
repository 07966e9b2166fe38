"""BlazePose run by hkpd: every person the detector finds, and 33 landmarks inside a region.

The two steps of BlazePose (Bazarevsky et al., "BlazePose: On-device Real-time Body Pose
tracking", 2020):

1. **Person detector** (:meth:`BlazePose.find_people`): the photo letterboxed into 224×224,
   scaled to [-1, 1]; per anchor a box, four keypoints and a score
   (:mod:`hkpd.prediction.detection.decoding`); kept above ``min_detection_confidence`` and merged
   by weighted non-maximum suppression. Each person's landmark region is the square around the
   hip centre whose side is 1.25 × the diameter of the full-body circle, rotated so the body's
   up is the crop's up (:func:`hkpd.prediction.detection.warp.person_region`).
2. **Landmark model** (:meth:`BlazePose.landmarks`): that region resampled to 256×256 in [0, 1];
   39 landmarks (the first 33 are BlazePose's), refined on their heatmaps, mapped back to the
   photo; visibility is the sigmoid of the visibility logit; a pose-presence score below
   :data:`POSE_PRESENCE_THRESHOLD` means no person in the region.

All coordinates are ``(u, v)`` pixels of the ``pixels`` given, pixel centres at integers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hkpd.prediction.detection.anchors import ssd_anchor_centres
from hkpd.prediction.detection.decoding import (
    decode_detections,
    decode_landmarks,
    sigmoid,
    weighted_nms,
)
from hkpd.prediction.detection.models import (
    DEFAULT_THREADS,
    DETECTOR_MODEL,
    LANDMARK_MODEL,
    SEGMENTATION_OUTPUT,
    TfliteModel,
    drop_output,
    read_blazepose_model,
)
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.detection.warp import (
    Region,
    crop,
    crop_matrix,
    letterbox_region,
    person_region,
)

BLAZEPOSE_LANDMARKS = 33
"""Landmarks BlazePose reports (the model's 6 auxiliary ones are dropped)."""

BLAZEPOSE_LANDMARK_NAMES = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
    "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
    "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip",
    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel",
    "right_heel", "left_foot_index", "right_foot_index",
)  # fmt: skip
"""BlazePose's 33 landmarks in model order (BlazePose's published topology)."""

REGION_SCALE = 1.25
"""Landmark region side / full-body circle diameter."""

POSE_PRESENCE_THRESHOLD = 0.5
"""The landmark model's pose-presence score below which a region holds no person."""


@dataclass(frozen=True)
class PersonCandidate:
    """One person found by the detector.

    Attributes:
        score: detector confidence in [0, 1].
        box: ``(4,)`` ``(x0, y0, x1, y1)`` detector box (the face and upper body, not the whole
            person), photo pixels.
        keypoints: ``(4, 2)`` hip centre, full-body circle point, shoulder centre, upper-body
            circle point, photo pixels.
        region: the landmark model's region for this person.
    """

    score: float
    box: np.ndarray
    keypoints: np.ndarray
    region: Region


@dataclass(frozen=True)
class PoseLandmarks:
    """BlazePose's 33 landmarks of the person in one region.

    Attributes:
        points: ``(33, 2)`` float64 photo pixels (outside the photo when the limb is).
        visibility: ``(33,)`` float64 in [0, 1].
        presence: pose-presence score in [0, 1].
        region: the region the landmark model looked at.
        mask: the person's segmentation probabilities over the region, in pixels of the
            ``pixels`` given; None when not asked for.
    """

    points: np.ndarray
    visibility: np.ndarray
    presence: float
    region: Region
    mask: PersonMask | None


class BlazePose:
    """The two models and the steps between them. Not thread-safe (callers serialise).

    Args:
        min_detection_confidence: the person detector's score threshold.
        threads: interpreter threads per model.
        segmentation: keep the landmark model's segmentation head (needed for
            ``landmarks(..., segmentation=True)``; the landmark outputs are identical either way,
            the head costs about 3.4 ms CPU a call, docs/benchmarks.md).
    """

    def __init__(
        self,
        min_detection_confidence: float = 0.5,
        threads: int = DEFAULT_THREADS,
        segmentation: bool = False,
    ) -> None:
        self.min_detection_confidence = min_detection_confidence
        self.segmentation = segmentation
        landmark_model = read_blazepose_model(LANDMARK_MODEL)
        if not segmentation:
            landmark_model = drop_output(landmark_model, SEGMENTATION_OUTPUT)
        self._detector = TfliteModel(read_blazepose_model(DETECTOR_MODEL), threads)
        self._landmarker = TfliteModel(landmark_model, threads)
        self._anchors = ssd_anchor_centres(self._detector.input_size)

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        """Every person the detector finds in ``(H, W, 3)`` uint8 RGB ``pixels``, best first."""
        height, width = pixels.shape[:2]
        letterbox = letterbox_region(width, height)
        size = self._detector.input_size
        image = crop(pixels, letterbox, size, replicate=False).astype(np.float32) / 127.5 - 1.0
        outputs = self._detector(image)
        raw_boxes, raw_scores = outputs["Identity"], outputs["Identity_1"]
        detections = weighted_nms(
            decode_detections(
                raw_boxes, raw_scores, self._anchors, self.min_detection_confidence, size
            )
        )
        people = []
        for box, keypoints, score in zip(
            detections.boxes, detections.keypoints, detections.scores, strict=True
        ):
            corners = letterbox.to_photo(box.reshape(2, 2)).reshape(4)
            points = letterbox.to_photo(keypoints)
            region = person_region(points[0], points[1], REGION_SCALE)
            people.append(PersonCandidate(float(score), corners, points, region))
        return people

    def landmarks(
        self, pixels: np.ndarray, region: Region, segmentation: bool = False
    ) -> PoseLandmarks:
        """BlazePose's 33 landmarks of the person in ``region`` of ``pixels``.

        Args:
            pixels: ``(H, W, 3)`` uint8 RGB.
            region: where to look (e.g. :attr:`PersonCandidate.region`).
            segmentation: also return the segmentation mask (:class:`PersonMask`).

        Raises:
            ValueError: ``segmentation`` asked of a runner made without it.
        """
        if segmentation and not self.segmentation:
            raise ValueError("this BlazePose was made without segmentation; pass segmentation=True")
        size = self._landmarker.input_size
        image = crop(pixels, region, size, replicate=True).astype(np.float32) / 255.0
        outputs = self._landmarker(image)
        found = decode_landmarks(outputs["Identity"], outputs["Identity_3"], size)
        presence = outputs["Identity_1"]
        mask = None
        if segmentation:
            logits = outputs[SEGMENTATION_OUTPUT][..., 0]
            mask = PersonMask(
                probability=sigmoid(logits).astype(np.float32),
                to_photo=crop_matrix(region, logits.shape[0]),
                image_size=(pixels.shape[1], pixels.shape[0]),
            )
        return PoseLandmarks(
            points=region.to_photo(found.points[:BLAZEPOSE_LANDMARKS]),
            visibility=found.visibility[:BLAZEPOSE_LANDMARKS],
            presence=float(np.asarray(presence).reshape(-1)[0]),
            region=region,
            mask=mask,
        )

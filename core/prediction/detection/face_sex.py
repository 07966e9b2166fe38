"""The face as evidence of apparent sex: the face cut from BlazePose's face landmarks, read by
HSE FaceRes (``faceres``, run by :mod:`hkpd.model_runtime`), gated and calibrated.

API (what the sex latent uses)::

    reader = FaceSexReader()                     # loads the shipped faceres on first use
    reading = reader.read(image_rgb, detection)  # -> FaceReading
    reading.p_male       # calibrated P(apparent sex male), or None when gated out
    reading.raw          # faceres's own output (sigmoid), None when no crop was read
    reading.age_years    # faceres's age (expectation over its 100 one-year bins), or None
    reading.face_px      # side of the face square, pixels of the image cut
    reading.reason       # None when read; else why the face gives no word (FACE_GATE_REASONS;
                         # "child": read, but faceres's age says a child: raw and age kept)
    readings = reader.read_all(image_rgb, detections)  # one batched network call

``detection`` is a :class:`~hkpd.prediction.detection.keypoint_detector.KeypointDetection`
(its ``face_landmarks``: BlazePose's landmarks 0-10 with visibilities) or an ``(11, 3)`` /
``(33, 3)`` array of BlazePose landmarks ``(u, v, visibility)`` in the image's pixels.

The face square (:func:`face_region`): centred a little below the eyes' midpoint, side
:data:`FACE_SIDE_PER_SCALE` × the face scale (the larger of the eye distance and the
eyes-to-mouth distance, so that a profile, whose eyes nearly coincide, keeps its size), turned
so that the face's right-to-left axis (the eye line plus the mouth-to-eyes axis turned a quarter)
is horizontal: the face is upright in the crop however the head is tilted. It is cut at
224 × 224, RGB in 0..255, the input Human (vladmandic/human ``src/face/faceres.ts``) gives the
model.

Gates (:data:`FACE_GATE_REASONS`; no face, no word): no face landmarks; the face outside the
photo; a back view (the eye line runs against the neck's direction:
:func:`facing_score` < :data:`MIN_FACING`); a face square under :data:`MIN_FACE_PX` pixels; a
face landmark less visible than :data:`MIN_LANDMARK_VISIBILITY`; an upside-down face (its up
more than :data:`MAX_FACE_TILT_DEGREES` from the photo's up, or eye line and mouth axis that
disagree); after reading, a face whose age is under :data:`CHILD_AGE_YEARS` (a child: the
young boy of train2017 read female, and the body model is adults'). The calibration
(:func:`calibrated_p_male`) maps faceres's logit, with the face's size as an input, to P(male)
under even odds. Constants were chosen and fitted on coco_mini train2017 and the demo photos
(``docs/experiments/face_sex_eval.py``; numbers in docs/shape.md).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from hkpd.model_runtime.shipped import load_human_model
from hkpd.prediction.detection.warp import Region, crop
from hkpd.prediction.image_input import LoadedImage

__all__ = [
    "FACE_GATE_REASONS",
    "FaceReading",
    "FaceSexReader",
    "calibrated_p_male",
    "face_gate",
    "face_region",
    "facing_score",
]

FACERES_INPUT_SIZE = 224
"""Side of faceres's input, pixels."""

FACE_SIDE_PER_SCALE = 3.2
"""Side of the face square / the face scale (max of eye distance and eyes-to-mouth distance)."""

FACE_CENTRE_BELOW_EYES = 0.3
"""How far below the eyes' midpoint the square is centred, in face scales."""

MIN_FACE_PX = 24.0
"""Smallest face square read, pixels (chosen on train2017 + demo photos: below it faceres ranks
women below men less often, AUC 0.94-0.97 against 0.98, and reads most small faces as men's)."""

MIN_FACING = -0.3
"""Smallest :func:`facing_score` read: below it the head is turned away (a back view)."""

MIN_LANDMARK_VISIBILITY = 0.5
"""Smallest BlazePose visibility of the nose, eyes and mouth corners for a face to be read."""

MAX_FACE_TILT_DEGREES = 120.0
"""Largest angle between the face's up and the photo's up for a face to be read."""

CALIBRATION = (-0.908, 2.35, 0.0)
"""``(offset, slope, slope per doubling of face size)`` of :func:`calibrated_p_male`, fitted in
``docs/experiments/face_sex_eval.py`` on the 37 read faces of coco_mini train2017 and the demo
photos (class-balanced maximum likelihood, so ``p / (1 - p)`` is a likelihood ratio under even
odds). The free fit's size slope came out negative (-0.20: two large, ambiguous men's faces), so
it was refitted at 0: small faces are kept out by :data:`MIN_FACE_PX` instead."""

CHILD_AGE_YEARS = 18.0
"""A face whose faceres age is under this gives no word on sex (reason ``"child"``): chosen on
train2017, where the children's faces read 10-28 years and the adults' 27-50, and the one child
read under 18 (a boy of about 3, 10 years) read female (0.18); the body model is adults' anyway."""

CALIBRATION_REFERENCE_PX = 60.0
"""Face size at which the calibration's slope is ``CALIBRATION[1]``, pixels."""

FACE_GATE_REASONS = {
    "no_face": "no face landmarks",
    "face_outside_photo": "the face is outside the photo",
    "back_view": "the head is turned away from the camera",
    "small_face": "the face is too small to read",
    "low_confidence": "the face landmarks are not confidently visible",
    "upside_down": "the face is upside down or its landmarks disagree",
    "child": "the face looks like a child's (faceres's age under CHILD_AGE_YEARS)",
}
"""Each gate's ``FaceReading.reason`` and what it means in words."""

NOSE, LEFT_EYE, RIGHT_EYE, LEFT_EAR, RIGHT_EAR, MOUTH_LEFT, MOUTH_RIGHT = 0, 2, 5, 7, 8, 9, 10
LEFT_SHOULDER, RIGHT_SHOULDER = 5, 6  # COCO-17 indices of KeypointDetection.keypoints
_READ_LANDMARKS = (NOSE, LEFT_EYE, RIGHT_EYE, MOUTH_LEFT, MOUTH_RIGHT)

FaceNetwork = Callable[[torch.Tensor], tuple[torch.Tensor, torch.Tensor]]
"""``(N, 224, 224, 3)`` float RGB 0..255 -> ``(N,)`` male logit, ``(N, 100)`` age probabilities."""


@dataclass(frozen=True)
class FaceReading:
    """What one face says.

    Attributes:
        p_male: calibrated P(apparent sex is male) in (0, 1); None when gated out.
        raw: faceres's own P(male) (its sigmoid), None when nothing was read.
        logit: faceres's male logit, None when nothing was read.
        age_years: faceres's apparent age, years (expectation over its bins), None when not read.
        face_px: side of the face square, pixels of the image cut (0 when there is no face).
        landmark_confidence: smallest BlazePose visibility of nose, eyes and mouth, in [0, 1].
        facing: :func:`facing_score` in [-1, 1] (1: facing the camera; None: unknown).
        reason: None when read, else a key of :data:`FACE_GATE_REASONS` (``"child"``: read,
            ``raw``/``logit``/``age_years`` kept, but no ``p_male``).
        region: the face square cut (None when there is no face).
    """

    p_male: float | None
    raw: float | None
    logit: float | None
    age_years: float | None
    face_px: float
    landmark_confidence: float
    facing: float | None
    reason: str | None
    region: Region | None = None


def _landmarks(detection: object) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(11, 3)`` face landmarks and ``(2,)`` shoulder midpoint (or None) of a detection or
    landmark array."""
    if isinstance(detection, np.ndarray):
        points = np.asarray(detection, np.float64)
        if points.ndim != 2 or points.shape[0] not in (11, 33) or points.shape[1] != 3:
            raise ValueError(
                f"face landmarks must be an (11, 3) or (33, 3) array of (u, v, visibility), "
                f"got shape {points.shape}"
            )
        shoulders = points[11:13, :2].mean(0) if points.shape[0] == 33 else None
        return points[:11], shoulders
    face = getattr(detection, "face_landmarks", None)
    keypoints = getattr(detection, "keypoints", None)
    shoulders = None
    if keypoints is not None:
        shoulders = np.asarray(keypoints, np.float64)[[LEFT_SHOULDER, RIGHT_SHOULDER]].mean(0)
    return (None if face is None else np.asarray(face, np.float64)), shoulders


def _face_axes(face: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eye line (right eye -> left eye), mouth-to-eyes axis and the eyes' midpoint, ``(2,)``
    pixels each."""
    eye_line = face[LEFT_EYE, :2] - face[RIGHT_EYE, :2]
    eyes = (face[LEFT_EYE, :2] + face[RIGHT_EYE, :2]) / 2
    mouth = (face[MOUTH_LEFT, :2] + face[MOUTH_RIGHT, :2]) / 2
    return eye_line, eyes - mouth, eyes


def face_region(face: np.ndarray) -> Region:
    """The face square of ``(11, 3)`` BlazePose face landmarks (pixels), level with the face.

    The face's left direction is the eye line plus the mouth-to-eyes axis turned a quarter
    clockwise in the photo (both point the same way on an upright face; the second dominates in
    profile, where the eyes nearly coincide); the square's "right" (crop +x) follows it, so the
    face is upright in the crop. Side :data:`FACE_SIDE_PER_SCALE` × the face scale, centred
    :data:`FACE_CENTRE_BELOW_EYES` face scales below the eyes' midpoint.
    """
    eye_line, up, eyes = _face_axes(face)
    across = eye_line + np.array([-up[1], up[0]])
    angle = math.atan2(across[1], across[0])
    scale = max(float(np.hypot(*eye_line)), float(np.hypot(*up)))
    down = np.array([-math.sin(angle), math.cos(angle)])
    centre = eyes + down * FACE_CENTRE_BELOW_EYES * scale
    return Region(centre, FACE_SIDE_PER_SCALE * scale, angle)


def facing_score(face: np.ndarray, shoulders: np.ndarray | None) -> float | None:
    """How squarely the face turns to the camera, in [-1, 1]: the sine of the angle from the
    neck's direction (shoulders' midpoint -> eyes' midpoint) to the eye line (right -> left
    eye). A face seen from the front has its left eye on the photo's right of its up (+1); a
    head seen from behind has it on the left (-1); profiles lie between. None without
    shoulders or with coinciding points."""
    if shoulders is None:
        return None
    eye_line, _, eyes = _face_axes(face)
    neck = eyes - shoulders
    norm = float(np.hypot(*neck) * np.hypot(*eye_line))
    if norm <= 1e-9:
        return None
    return float((neck[0] * eye_line[1] - neck[1] * eye_line[0]) / norm)


def face_gate(
    face: np.ndarray | None,
    shoulders: np.ndarray | None,
    image_size: tuple[int, int],
    min_face_px: float = MIN_FACE_PX,
) -> tuple[str | None, Region | None, float | None]:
    """Why a face gives no word (a key of :data:`FACE_GATE_REASONS`, or None to read it), its
    square and its :func:`facing_score`. ``image_size``: ``(width, height)`` of the image the
    landmarks' pixels refer to; ``min_face_px``: the smallest face square read."""
    if face is None or not np.isfinite(face).all():
        return "no_face", None, None
    eye_line, up, eyes = _face_axes(face)
    if max(float(np.hypot(*eye_line)), float(np.hypot(*up))) < 1e-6:
        return "no_face", None, None
    region = face_region(face)
    facing = facing_score(face, shoulders)
    width, height = image_size
    inside = [(0 <= u <= width - 1) and (0 <= v <= height - 1) for u, v in (eyes, eyes - up)]
    if not all(inside):
        return "face_outside_photo", region, facing
    if facing is not None and facing < MIN_FACING:
        return "back_view", region, facing
    if region.size < min_face_px:
        return "small_face", region, facing
    if float(face[list(_READ_LANDMARKS), 2].min()) < MIN_LANDMARK_VISIBILITY:
        return "low_confidence", region, facing
    tilt = math.degrees(abs(math.atan2(up[0], -up[1])))
    turned = float(eye_line @ np.array([-up[1], up[0]])) < 0
    if tilt > MAX_FACE_TILT_DEGREES or turned:
        return "upside_down", region, facing
    return None, region, facing


def calibrated_p_male(
    logit: float | np.ndarray, face_px: float | np.ndarray, calibration=CALIBRATION
) -> np.ndarray:
    """P(male) from faceres's male ``logit`` and the face square's side ``face_px`` (pixels):
    ``sigmoid(a + (b + c·log2(face_px / 60)) · logit)`` with ``(a, b, c) = calibration``;
    the size term is clipped to [-2, 2] doublings and the slope kept non-negative. Arrays
    broadcast."""
    offset, slope, per_doubling = calibration
    doublings = np.clip(np.log2(np.asarray(face_px, np.float64) / CALIBRATION_REFERENCE_PX), -2, 2)
    gain = np.maximum(slope + per_doubling * doublings, 0.0)
    return 1.0 / (1.0 + np.exp(-(offset + gain * np.asarray(logit, np.float64))))


def load_faceres(device: str | torch.device = "cpu") -> FaceNetwork:
    """The shipped faceres (:func:`hkpd.model_runtime.shipped.load_human_model`) as a
    :data:`FaceNetwork` on ``device``."""
    model = load_human_model("faceres").to(device)

    def run(faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = model.run({"input_1": faces}, ["gender_pred/BiasAdd", "age_pred/Softmax"])
        return out["gender_pred/BiasAdd"][:, 0], out["age_pred/Softmax"]

    return run


class FaceSexReader:
    """Reads apparent sex (and age) from people's faces; thread-safe, the network is loaded on
    first use and shared.

    Args:
        network: a :data:`FaceNetwork` (default: the shipped faceres, :func:`load_faceres`).
        device: where the default network runs.
        min_face_px: the smallest face square read (:data:`MIN_FACE_PX`).
        calibration: ``(offset, slope, slope per doubling)`` of :func:`calibrated_p_male`.
    """

    def __init__(
        self,
        network: FaceNetwork | None = None,
        device: str = "cpu",
        min_face_px: float = MIN_FACE_PX,
        calibration: tuple[float, float, float] = CALIBRATION,
    ) -> None:
        self._network = network
        self._device = device
        self.min_face_px = min_face_px
        self.calibration = calibration
        self._lock = threading.Lock()

    def _net(self) -> FaceNetwork:
        with self._lock:
            if self._network is None:
                self._network = load_faceres(self._device)
            return self._network

    def read(self, image: np.ndarray | LoadedImage, detection: object) -> FaceReading:
        """The :class:`FaceReading` of one person (see :meth:`read_all`)."""
        return self.read_all(image, [detection])[0]

    def read_all(
        self, image: np.ndarray | LoadedImage, detections: Sequence[object]
    ) -> list[FaceReading]:
        """One :class:`FaceReading` per detection, the faces read in one batch.

        Args:
            image: ``(H, W, 3)`` uint8 RGB photo whose pixels the detections' coordinates
                refer to, or a :class:`LoadedImage` (detections in original-photo pixels, as
                :class:`KeypointDetection` gives them; its working pixels are cut).
            detections: KeypointDetections, or ``(11, 3)`` / ``(33, 3)`` landmark arrays.

        Raises:
            ValueError: ``image`` is not an RGB uint8 array, or a landmark array is malformed.
        """
        pixels, to_pixels = _pixels_and_map(image)
        gated, regions, kept = [], [], []
        for index, detection in enumerate(detections):
            face, shoulders = _landmarks(detection)
            if face is not None:
                face = face.copy()
                face[:, :2] = to_pixels(face[:, :2])
                shoulders = None if shoulders is None else to_pixels(shoulders)
            size = (pixels.shape[1], pixels.shape[0])
            reason, region, facing = face_gate(face, shoulders, size, self.min_face_px)
            confidence = 0.0 if face is None else float(face[list(_READ_LANDMARKS), 2].min())
            gated.append((reason, region, facing, confidence))
            if reason is None:
                regions.append(region)
                kept.append(index)
        logits, ages = self._run(pixels, regions)
        values = dict(zip(kept, zip(logits, ages, strict=True), strict=True))
        return [
            _reading(*gated[i], values.get(i), self.calibration) for i in range(len(detections))
        ]

    def _run(self, pixels: np.ndarray, regions: list[Region]) -> tuple[list[float], list[float]]:
        """Male logits and ages (years) of the face squares ``regions`` of ``pixels``."""
        if not regions:
            return [], []
        faces = np.stack([crop(pixels, r, FACERES_INPUT_SIZE, replicate=True) for r in regions])
        logit, age = self._net()(torch.from_numpy(faces).float())
        years = age.float() @ torch.arange(age.shape[-1], dtype=torch.float32, device=age.device)
        return logit.float().cpu().tolist(), years.cpu().tolist()


def _reading(
    reason: str | None,
    region: Region | None,
    facing: float | None,
    confidence: float,
    value: tuple[float, float] | None,
    calibration: tuple[float, float, float] = CALIBRATION,
) -> FaceReading:
    """A :class:`FaceReading` from a gate's outcome and, when read, ``(logit, age)``."""
    face_px = 0.0 if region is None else float(region.size)
    if value is None:
        return FaceReading(None, None, None, None, face_px, confidence, facing, reason, region)
    logit, age = value
    raw = 1.0 / (1.0 + math.exp(-logit))
    if age < CHILD_AGE_YEARS:
        return FaceReading(None, raw, logit, age, face_px, confidence, facing, "child", region)
    p_male = float(calibrated_p_male(logit, face_px, calibration))
    return FaceReading(p_male, raw, logit, age, face_px, confidence, facing, None, region)


def _pixels_and_map(
    image: np.ndarray | LoadedImage,
) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
    """The pixels to cut and the map from the detections' pixels to theirs."""
    if isinstance(image, LoadedImage):
        sx, sy = image.scale
        scale = np.array([sx, sy])
        return image.pixels, lambda points: (np.asarray(points) + 0.5) * scale - 0.5
    pixels = np.asarray(image)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype != np.uint8:
        raise ValueError(
            f"the photo must be an (H, W, 3) uint8 RGB array, got {pixels.dtype} {pixels.shape}"
        )
    return pixels, lambda points: np.asarray(points, np.float64)

"""How well the posterior's body covers the person on real photos: silhouette IoU against the
human-drawn COCO masks.

For each annotated person with a polygon mask (:class:`hkpd.evaluation.real_photos.AnnotatedPerson`)
the predictor's posterior is computed as ``hkpd-predict`` does, and three masks in the photo's
pixels are compared with the COCO mask by intersection over union:

- ``mode``: the mode mesh's silhouette, rendered over the crop box with the posterior's camera
  (:func:`hkpd.prediction.exports.fit_overlay.render_fit_overlay`, the picture the overview and
  the explorer draw) and mapped into the photo with the crop;
- ``average shape``: the same pose and camera with the average shape (all coefficients 0), so
  ``mode - average shape`` is what reading the shape buys;
- ``detector``: BlazePose's own mask (``NetworkInput.person_mask``, the probability in crop
  pixels, at 0.5), when the detector gave one (else None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
import torch
from tqdm import tqdm

from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.detection.person_mask import MASK_THRESHOLD
from hkpd.prediction.exports.fit_overlay import render_fit_overlay
from hkpd.prediction.image_input import ImageInputError
from hkpd.prediction.posterior import BodyPosterior, CropToImage
from hkpd.prediction.predictor import Predictor


def mask_iou(predicted: np.ndarray, target: np.ndarray) -> float:
    """Intersection over union of two ``(H, W)`` bool masks (NaN when both are empty)."""
    if predicted.shape != target.shape:
        raise ValueError(f"masks differ in shape: {predicted.shape} and {target.shape}")
    union = np.logical_or(predicted, target).sum()
    if union == 0:
        return math.nan
    return float(np.logical_and(predicted, target).sum() / union)


def crop_mask_in_photo(
    mask: np.ndarray, crop: CropToImage, photo_size: tuple[int, int]
) -> np.ndarray:
    """``(S, S)`` crop-pixel mask (bool or probability) -> ``(H, W)`` bool photo mask.

    Args:
        mask: in the crop's pixels (``S = crop.size``; another size is scaled to it).
        crop: the posterior's crop (crop pixels -> photo pixels, pixel-edge coordinates).
        photo_size: ``(width, height)`` of the photo.
    """
    size = crop.size
    values = mask.astype(np.float32)
    if values.shape != (size, size):
        values = cv2.resize(values, (size, size), interpolation=cv2.INTER_LINEAR)
    corners = np.array([[0.0, 0.0], [size - 1.0, 0.0], [0.0, size - 1.0]])
    photo = np.asarray(crop.crop_to_image(corners), dtype=np.float64) - 0.5  # cv2: centres
    affine = cv2.getAffineTransform(corners.astype(np.float32), photo.astype(np.float32))
    warped = cv2.warpAffine(values, affine, photo_size, flags=cv2.INTER_LINEAR, borderValue=0.0)
    return warped >= MASK_THRESHOLD


def mode_silhouette(posterior: BodyPosterior) -> np.ndarray:
    """``(S, S)`` bool, the mode mesh's pixels in the posterior's crop."""
    overlay = render_fit_overlay(posterior, size=posterior.crop.size)
    return overlay.rgba[..., 3] > 0


def with_average_shape(posterior: BodyPosterior) -> BodyPosterior:
    """``posterior`` with the average shape (coefficients 0): the same pose and camera."""
    average = torch.zeros_like(posterior.shape_mean)
    return replace(posterior, distribution=replace(posterior.distribution, shape_mean=average))


@dataclass(frozen=True)
class PersonSilhouettes:
    """One person's IoUs against the COCO mask.

    Attributes:
        split: the photo's folder (``val2017``, ``train2017``).
        mode_iou: the mode's silhouette.
        average_shape_iou: the same with the average shape.
        detector_iou: BlazePose's mask, or None when the detector gave none.
    """

    split: str
    mode_iou: float
    average_shape_iou: float
    detector_iou: float | None


def person_silhouettes(posterior: BodyPosterior, person: AnnotatedPerson) -> PersonSilhouettes:
    """The IoUs of ``posterior``'s masks against ``person``'s COCO mask."""
    target = person.silhouette()
    size = person.image_size

    def iou(crop_mask: np.ndarray) -> float:
        return mask_iou(crop_mask_in_photo(crop_mask, posterior.crop, size), target)

    detector_mask = posterior.network_input.person_mask
    return PersonSilhouettes(
        split=person.image_path.parent.name,
        mode_iou=iou(mode_silhouette(posterior)),
        average_shape_iou=iou(mode_silhouette(with_average_shape(posterior))),
        detector_iou=None if detector_mask is None else iou(np.asarray(detector_mask)),
    )


def evaluate_coco_silhouettes(
    predictor: Predictor, people: list[AnnotatedPerson], evidence: bool, show_progress: bool = True
) -> list[PersonSilhouettes]:
    """:func:`person_silhouettes` of every person with a polygon mask whom the detector finds
    (the network's posterior, or with ``evidence`` the evidence posterior)."""
    results = []
    for person in tqdm(people, disable=not show_progress, unit="person"):
        if not person.outlines:
            continue
        try:
            posterior = predictor.predict(
                person.image_path, bbox=person.search_box(), evidence=evidence
            )
        except (NoPersonFoundError, ImageInputError, ValueError):
            continue
        results.append(person_silhouettes(posterior, person))
    return results


def coco_record(
    by_posterior: dict[str, list[PersonSilhouettes]],
) -> dict[str, dict[str, object]]:
    """Mean IoUs per photo folder and over ``"all"``, for ``shape.json``.

    Args:
        by_posterior: each posterior's (``"network"``, ``"evidence"``) per-person results.

    Returns:
        ``{split: {posterior: {"mode_iou", "average_shape_iou", "people"}, "detector_iou"}}``;
        ``detector_iou`` is the mean over the people with a detector mask (the detector does
        not depend on the posterior), None when none had one.
    """
    every = [result for results in by_posterior.values() for result in results]
    splits = [*sorted({result.split for result in every}), "all"]
    record: dict[str, dict[str, object]] = {}
    for split in splits:
        entry: dict[str, object] = {}
        detector: list[float] = []
        for name, results in by_posterior.items():
            group = [r for r in results if split in ("all", r.split)]
            entry[name] = {
                "mode_iou": _nanmean([r.mode_iou for r in group]),
                "average_shape_iou": _nanmean([r.average_shape_iou for r in group]),
                "people": len(group),
            }
            if not detector:
                detector = [r.detector_iou for r in group if r.detector_iou is not None]
        entry["detector_iou"] = _nanmean(detector) if detector else None
        record[split] = entry
    return record


def _nanmean(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan

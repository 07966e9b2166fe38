"""How BlazePose's person mask differs from the human-drawn COCO masks: its IoU, where it errs,
and the numbers behind a detector-like synthetic mask (docs/shape.md, "The mask").

For each annotated person (with a polygon mask) the detector runs inside the person's widened
box (:meth:`AnnotatedPerson.search_box`, as :func:`hkpd.evaluation.real_photos.evaluate_photos`
does), and both masks are compared **in the network's crop at 256 pixels**, framed as the
predictor frames it (:meth:`CropTransform.from_keypoints` on the detection): BlazePose's mask
through :func:`hkpd.prediction.network_input.crop_person_mask`, thresholded at 0.5, and the
COCO polygon mask resampled into the same crop. Only pixels inside the photo count.

Where it errs, as shares of the COCO mask's area (``B`` = :data:`BOUNDARY_BAND_PX`):

- **boundary, outward**: mask pixels outside the COCO mask but within ``B`` of it (hair, loose
  clothing, blur, the annotators' polygon simplification);
- **other people** / **background**: mask pixels further than ``B`` from the COCO mask, on
  another annotated person of the photo or not;
- **boundary, inward**: COCO pixels the mask misses within ``B`` of the mask;
- **missed parts**: COCO pixels further than ``B`` from the mask (thin limbs, hands, parts
  behind an object that the annotator drew, or the wrong person).

The degradation numbers: the signed **offset** of the mask's edge from the COCO edge along
the mask's boundary pixels within ``B`` (crop pixels, + outward), its mean, spread, and the
means of the outward and inward parts; the share of the person **missed** (missed parts);
**spurious blobs**: connected far-away false-positive regions of at least
:data:`MIN_BLOB_PX` pixels, per person, and their area. Use a split you do not report results
on for tuning (coco_mini's train2017); report val2017 separately.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import cv2
import numpy as np

from hkpd.evaluation.real_photos import AnnotatedPerson
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.keypoint_detector import KeypointDetection, NoPersonFoundError
from hkpd.prediction.detection.person_mask import MASK_THRESHOLD
from hkpd.prediction.image_input import ImageInputError
from hkpd.prediction.network_input import crop_person_mask, mask_known
from hkpd.prediction.occluders import Occluders

MASK_CROP_SIZE = 256
"""Side of the crop the masks are compared in, pixels (the network's)."""

BOUNDARY_BAND_PX = 8.0
"""Errors within this distance of the other mask (crop pixels at 256, about 3 % of the crop,
a fifth of a forearm's width) count as boundary errors; fixed before measuring, not tuned."""

MIN_BLOB_PX = 20
"""Smallest far-away false-positive region counted as a spurious blob, crop pixels."""

WRONG_PERSON_IOU = 0.1
"""Below this IoU the mask is of someone (or something) else: counted, and kept in the means."""


@dataclass(frozen=True)
class PersonMaskErrors:
    """One person's mask against the COCO mask (shares are of the COCO mask's area).

    Attributes:
        iou: intersection over union of the thresholded mask and the COCO mask.
        boundary_outward, other_people, background: false-positive shares (see the module).
        boundary_inward, missed_parts: false-negative shares.
        offsets: ``(N,)`` signed offsets of the mask's boundary pixels within the band, crop
            pixels at 256 (+ outward).
        blobs: spurious blobs (far-away false-positive regions of >= :data:`MIN_BLOB_PX`).
        truth_pixels: the COCO mask's area in the crop, pixels.
    """

    iou: float
    boundary_outward: float
    other_people: float
    background: float
    boundary_inward: float
    missed_parts: float
    offsets: np.ndarray
    blobs: int
    truth_pixels: int


@dataclass(frozen=True)
class MaskErrors:
    """Summary over people: means of the per-person values, offsets pooled.

    Attributes:
        mean_iou, median_iou: of the per-person IoU.
        boundary_outward, other_people, background, boundary_inward, missed_parts: mean shares.
        offset_mean_px, offset_std_px: of the pooled signed boundary offsets (+ outward).
        outward_mean_px, inward_mean_px: mean size of the outward / inward offsets.
        outward_share: share of boundary pixels outside the COCO mask.
        blobs_per_person: mean spurious blobs per person.
        wrong_person: people whose IoU is below :data:`WRONG_PERSON_IOU`.
        people: people measured; failed: people the detector found nothing for.
    """

    mean_iou: float
    median_iou: float
    boundary_outward: float
    other_people: float
    background: float
    boundary_inward: float
    missed_parts: float
    offset_mean_px: float
    offset_std_px: float
    outward_mean_px: float
    inward_mean_px: float
    outward_share: float
    blobs_per_person: float
    wrong_person: int
    people: int
    failed: int

    def row(self) -> dict[str, float]:
        """The summary as a table row ``{field name: value}``."""
        return {field.name: float(getattr(self, field.name)) for field in fields(self)}


def compare_masks(
    predicted: np.ndarray, truth: np.ndarray, others: np.ndarray, known: np.ndarray
) -> PersonMaskErrors:
    """One person's errors from masks in the same crop.

    Args:
        predicted: ``(S, S)`` bool, the detector's mask (thresholded).
        truth: ``(S, S)`` bool, the person's COCO mask.
        others: ``(S, S)`` bool, the other annotated people of the photo.
        known: ``(S, S)`` bool, the pixels that count (inside the photo).

    Raises:
        ValueError: the COCO mask is empty where it counts.
    """
    predicted, truth = predicted & known, truth & known
    area = int(truth.sum())
    if area == 0:
        raise ValueError("the COCO mask is empty inside the photo's part of the crop")
    to_truth, _ = _distances(truth)
    _, inside_truth = _distances(truth | ~known)  # the photo's edge is no edge of the person
    to_predicted, _ = _distances(predicted)
    false_positive, false_negative = predicted & ~truth, truth & ~predicted
    near = to_truth <= BOUNDARY_BAND_PX
    far_positive = false_positive & ~near
    missed = false_negative & (to_predicted > BOUNDARY_BAND_PX)
    boundary = _boundary(predicted, known)
    # The edge lies half a pixel outside a boundary pixel's centre: +d outside, 1 - d inside.
    offsets = np.where(truth, 1.0 - inside_truth, to_truth)[boundary]
    count, _, stats, _ = cv2.connectedComponentsWithStats(far_positive.astype(np.uint8), 8)
    return PersonMaskErrors(
        iou=float((predicted & truth).sum() / (predicted | truth).sum()),
        boundary_outward=float((false_positive & near).sum() / area),
        other_people=float((far_positive & others).sum() / area),
        background=float((far_positive & ~others).sum() / area),
        boundary_inward=float((false_negative & ~missed).sum() / area),
        missed_parts=float(missed.sum() / area),
        offsets=offsets[np.abs(offsets) <= BOUNDARY_BAND_PX],
        blobs=int((stats[1:count, cv2.CC_STAT_AREA] >= MIN_BLOB_PX).sum()),
        truth_pixels=area,
    )


def _boundary(mask: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``(S, S)`` bool: pixels of ``mask`` next to (8-neighbourhood) a known pixel outside it;
    the crop's frame is left out (what lies beyond it is not seen)."""
    grown = (mask | ~known).astype(np.uint8)
    boundary = mask & ~cv2.erode(grown, np.ones((3, 3), np.uint8)).astype(bool)
    boundary[[0, -1], :] = False
    boundary[:, [0, -1]] = False
    return boundary


def _distances(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(S, S)`` float distances (pixels, Euclidean): from each pixel outside ``mask`` to its
    nearest pixel inside (0 inside), and from each pixel inside to its nearest outside (0
    outside). An empty mask is infinitely far; a full one has no outside (infinite)."""
    if not mask.any():
        return np.full(mask.shape, np.inf), np.zeros(mask.shape)
    if mask.all():
        return np.zeros(mask.shape), np.full(mask.shape, np.inf)
    outside = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    inside = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return outside, inside


def person_masks_in_crop(
    detection: KeypointDetection, person: AnnotatedPerson, others: Sequence[AnnotatedPerson]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The detector's mask, the person's and the others' COCO masks, and the photo's pixels, in
    the network's crop at :data:`MASK_CROP_SIZE` (all ``(S, S)`` bool).

    Raises:
        ValueError: the detection has no mask (a detector without segmentation).
    """
    if detection.person_mask is None:
        raise ValueError("the detector gave no mask: use KeypointDetector(segmentation=True)")
    crop = CropTransform.from_keypoints(
        detection.keypoints,
        detection.confidences,
        image_size=detection.image_size,
        size=MASK_CROP_SIZE,
    )
    predicted = crop_person_mask(detection.person_mask, crop) > MASK_THRESHOLD
    known = mask_known(crop, detection.image_size, Occluders.of(None))
    truth = _in_crop(person.silhouette(), crop)
    other = np.zeros_like(truth)
    for someone in others:
        if someone.outlines:
            other |= _in_crop(someone.silhouette(), crop)
    return predicted, truth, other & ~truth, known


def _in_crop(silhouette: np.ndarray, crop: CropTransform) -> np.ndarray:
    """``(H, W)`` bool photo mask -> ``(S, S)`` bool crop mask (bilinear, at one half)."""
    return crop.crop_image(silhouette.astype(np.uint8) * 255) >= 128


def mask_errors(
    detector, people: Sequence[AnnotatedPerson], everyone: Sequence[AnnotatedPerson]
) -> tuple[MaskErrors, list[PersonMaskErrors]]:
    """Run ``detector`` (a :class:`hkpd.prediction.KeypointDetector` with segmentation) on
    ``people`` (those with a polygon mask are measured) and compare its masks with theirs;
    ``everyone`` are all annotated people (for the "other people" share)."""
    by_photo: dict[Path, list[AnnotatedPerson]] = {}
    for someone in everyone:
        by_photo.setdefault(someone.image_path, []).append(someone)
    measured, failed = [], 0
    for person in people:
        if not person.outlines:
            continue
        try:
            detection = detector.detect(str(person.image_path), bbox=person.search_box())
        except (NoPersonFoundError, ImageInputError, ValueError):
            failed += 1
            continue
        others = [p for p in by_photo.get(person.image_path, []) if not _same(p, person)]
        masks = person_masks_in_crop(detection, person, others)
        try:
            measured.append(compare_masks(*masks))
        except ValueError:
            failed += 1
    return summarise(measured, failed), measured


def _same(first: AnnotatedPerson, second: AnnotatedPerson) -> bool:
    """The same annotation (photo and box)."""
    return first.image_path == second.image_path and np.array_equal(first.bbox, second.bbox)


def summarise(measured: Sequence[PersonMaskErrors], failed: int = 0) -> MaskErrors:
    """The :class:`MaskErrors` of per-person results (NaN means when there are none)."""

    def mean(name: str) -> float:
        values = [getattr(m, name) for m in measured]
        return float(np.mean(values)) if values else float("nan")

    offsets = np.concatenate([m.offsets for m in measured]) if measured else np.zeros(0)
    outward, inward = offsets[offsets > 0], -offsets[offsets <= 0]
    ious = [m.iou for m in measured]
    return MaskErrors(
        mean_iou=mean("iou"),
        median_iou=float(np.median(ious)) if ious else float("nan"),
        boundary_outward=mean("boundary_outward"),
        other_people=mean("other_people"),
        background=mean("background"),
        boundary_inward=mean("boundary_inward"),
        missed_parts=mean("missed_parts"),
        offset_mean_px=float(offsets.mean()) if offsets.size else float("nan"),
        offset_std_px=float(offsets.std()) if offsets.size else float("nan"),
        outward_mean_px=float(outward.mean()) if outward.size else float("nan"),
        inward_mean_px=float(inward.mean()) if inward.size else float("nan"),
        outward_share=float(outward.size / offsets.size) if offsets.size else float("nan"),
        blobs_per_person=mean("blobs"),
        wrong_person=sum(m.iou < WRONG_PERSON_IOU for m in measured),
        people=len(measured),
        failed=failed,
    )


MASK_ERROR_COLUMNS = {
    "mean_iou": "mean IoU",
    "median_iou": "median IoU",
    "boundary_outward": "FP boundary",
    "other_people": "FP other people",
    "background": "FP background",
    "boundary_inward": "FN boundary",
    "missed_parts": "FN missed parts",
    "offset_mean_px": "edge offset px",
    "offset_std_px": "offset std px",
    "outward_mean_px": "outward px",
    "inward_mean_px": "inward px",
    "outward_share": "outward share",
    "blobs_per_person": "blobs / person",
    "wrong_person": "wrong person",
    "people": "people",
    "failed": "not found",
}
"""The table's columns and their headers (shares are of the COCO mask's area)."""


def mask_error_table(results: dict[str, MaskErrors]) -> str:
    """A markdown table, one row per split (``{split: summary}``), with a line on the method."""
    header = "| split | " + " | ".join(MASK_ERROR_COLUMNS.values()) + " |"
    lines = [header, "|---|" + "---|" * len(MASK_ERROR_COLUMNS)]
    for split, summary in results.items():
        row = summary.row()
        cells = [_cell(row[name]) for name in MASK_ERROR_COLUMNS]
        lines.append(f"| {split} | " + " | ".join(cells) + " |")
    note = (
        f"In the network's crop at {MASK_CROP_SIZE} px, BlazePose's mask at probability "
        f"{MASK_THRESHOLD}; FP/FN shares are of the COCO mask's area, boundary = within "
        f"{BOUNDARY_BAND_PX:g} px of the other mask; edge offsets + outward."
    )
    return "\n".join(lines) + "\n\n" + note + "\n"


def _cell(value: float) -> str:
    """Counts as integers, the rest with three decimals (two for pixels above 1)."""
    if np.isnan(value):
        return "n/a"
    if float(value).is_integer() and abs(value) >= 1:
        return f"{int(value)}"
    return f"{value:.3f}" if abs(value) < 1 else f"{value:.2f}"


def split_mask_errors(
    detector, people: Sequence[AnnotatedPerson], everyone: Sequence[AnnotatedPerson]
) -> dict[str, MaskErrors]:
    """:func:`mask_errors` of each split (the photos' folder name, e.g. ``val2017``) apart."""
    splits = sorted({person.image_path.parent.name for person in people})
    return {
        split: mask_errors(
            detector, [p for p in people if p.image_path.parent.name == split], everyone
        )[0]
        for split in splits
    }

"""Readings with known errors, to choose and measure the quality score (:mod:`~hkpd.prediction`'s
``quality``).

Two sources, each giving :class:`QualityReading` rows (the score's signals and the reading's
error as a fraction of the person's size):

- **coco_mini** people, read through the annotated box grown by 15 % (as ``hkpd-eval --coco``
  does) or through the detector's own person boxes (:meth:`Predictor.predict_all`'s boxes,
  each matched to an annotated person by box overlap): the second is how a user's photos are
  read, and where readings go off.
- **Synthetic photos with hard cases** (:func:`hard_synthetic_photos`): rendered people (the
  training renderer: procedural poses, any facing, rolled and steep views, occluder boxes and
  erased parts) pasted on a larger cluttered canvas at a random size (down to ~40 pixels),
  often cut off by the canvas' edge, sometimes blurred and low in contrast, sometimes with a
  second person beside them (then read in the first one's search box); the detector finds the
  person as it would in a photo.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from tqdm import tqdm

from hkpd.evaluation.quality_metrics import quality_table
from hkpd.evaluation.real_photos import AnnotatedPerson, load_coco_people
from hkpd.poses import pose_source
from hkpd.prediction.detection.boxes import box_iou
from hkpd.prediction.detection.keypoint_detector import (
    NoPersonFoundError,
    people_by_size,
    reading_box,
)
from hkpd.prediction.image_input import ImageInputError, load_image
from hkpd.prediction.quality import SIGNAL_NAMES
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator
from hkpd.synthesis.orientation import TRAINING_MIX

MIN_SCORED_KEYPOINTS = 6
"""A reading is scored only when the truth shows at least this many keypoints."""

MATCH_IOU = 0.3
"""A detected person is an annotated one when their boxes overlap by at least this IoU."""

HARD_AUGMENTATION = AugmentationConfig(
    body_part_occlusion_probability=0.2,
    half_image_occlusion_probability=0.05,
    occlusion_box_probability=0.5,
    limb_occlusion_probability=0.25,
)
"""The synthetic photos' occlusions: erased parts, boxes, half-images and boxes over limbs
(the training augmentations, more often)."""

CANVAS = 512
"""Side of the synthetic photos, pixels (the person's 256-px render is pasted on it)."""

DISTRACTOR_PROBABILITY = 0.4
"""Share of the synthetic photos with a second person beside the first."""


@dataclass(frozen=True)
class QualityReading:
    """One reading with a known error.

    Attributes:
        source: where it came from (e.g. ``"val2017/detector"``, ``"synthetic"``).
        name: the photo (and person) it reads.
        signals: ``(S,)`` the quality signals (:data:`hkpd.prediction.quality.SIGNAL_NAMES`).
        error: mean distance of the mode's keypoints from the true visible ones / the person's
            size.
        score: the shipped quality score of the reading.
        flags: its quality flags.
    """

    source: str
    name: str
    signals: np.ndarray
    error: float
    score: float
    flags: tuple[str, ...]


@dataclass(frozen=True)
class SyntheticPhoto:
    """A synthetic photo and its truth.

    Attributes:
        image: ``(H, W, 3)`` uint8 RGB.
        keypoints: ``(17, 2)`` true COCO keypoints, photo pixels.
        visible: ``(17,)`` bool: inside the photo and not hidden (by the body or an occluder).
        size: the visible person's larger side, pixels (as COCO's annotated boxes).
        search_box: ``(4,)`` where to look for the person (their visible box grown by 15 %)
            when another person stands beside them; None: read the photo as a whole.
    """

    image: np.ndarray
    keypoints: np.ndarray
    visible: np.ndarray
    size: float
    search_box: np.ndarray | None = None


def reading_error(
    mode_points: np.ndarray, truth: np.ndarray, visible: np.ndarray, size: float
) -> float:
    """Mean distance of ``(17, 2)`` mode keypoints from ``(17, 2)`` true ones over the
    ``(17,)`` visible ones, as a fraction of ``size`` (pixels)."""
    distance = np.linalg.norm(np.asarray(mode_points) - np.asarray(truth), axis=-1)
    return float(distance[np.asarray(visible, bool)].mean() / size)


def _reading(source: str, name: str, posterior, truth, visible, size: float) -> QualityReading:
    quality = posterior.quality
    mode = posterior.mode().keypoints2d[0].detach().cpu().double().numpy()
    signals = np.array([quality.signals[key] for key in SIGNAL_NAMES])
    error = reading_error(mode, truth, visible, size)
    return QualityReading(source, name, signals, error, quality.score, quality.flags)


def coco_readings(
    predictor,
    coco_dir: Path,
    boxes: str = "annotated",
    show_progress: bool = True,
    split: str | None = None,
) -> list[QualityReading]:
    """Every coco_mini person with >= 6 visible keypoints read through its annotated box
    (``boxes="annotated"``) or every person the detector lists and that matches an annotated
    one (``"detector"``); people the detector misses are not scored. ``split``: only the photos
    of that split (e.g. ``"val2017"``)."""
    if boxes not in ("annotated", "detector"):
        raise ValueError(f"boxes must be 'annotated' or 'detector', got {boxes!r}")
    people = load_coco_people(coco_dir, min_visible=MIN_SCORED_KEYPOINTS)
    if split is not None:
        people = [person for person in people if person.image_path.parent.name == split]
    if boxes == "annotated":
        return list(_annotated_readings(predictor, people, show_progress))
    return list(_detector_readings(predictor, people, show_progress))


def _annotated_readings(predictor, people, show_progress: bool) -> Iterator[QualityReading]:
    for person in tqdm(people, disable=not show_progress, unit="person"):
        try:
            posterior = predictor.predict(person.image_path, bbox=person.search_box())
        except (NoPersonFoundError, ImageInputError, ValueError):
            continue
        yield _person_reading(f"{person.image_path.parent.name}/annotated", person, posterior)


def _person_reading(source: str, person: AnnotatedPerson, posterior) -> QualityReading:
    size = float((person.bbox[2:] - person.bbox[:2]).max())
    name = f"{person.image_path.name}@{','.join(f'{v:.0f}' for v in person.bbox)}"
    return _reading(source, name, posterior, person.keypoints, person.visible, size)


def _detector_readings(predictor, people, show_progress: bool) -> Iterator[QualityReading]:
    by_photo: dict[Path, list[AnnotatedPerson]] = {}
    for person in people:
        by_photo.setdefault(person.image_path, []).append(person)
    for path, annotated in tqdm(by_photo.items(), disable=not show_progress, unit="photo"):
        loaded = load_image(path)
        found = people_by_size(predictor.detector.detect_all(loaded))
        taken: set[int] = set()
        for detection in found:
            match = _best_match(detection.person_box, annotated, taken)
            if match is None:
                continue
            taken.add(match)
            try:
                posterior = predictor.predict(loaded, bbox=reading_box(detection))
            except (NoPersonFoundError, ValueError):
                continue
            source = f"{path.parent.name}/detector"
            yield _person_reading(source, annotated[match], posterior)


def _best_match(box, annotated: list[AnnotatedPerson], taken: set[int]) -> int | None:
    """The untaken annotated person whose box overlaps ``box`` most (IoU >= MATCH_IOU)."""
    best, best_iou = None, MATCH_IOU
    for index, person in enumerate(annotated):
        overlap = box_iou(np.asarray(box, np.float64), person.bbox)
        if index not in taken and overlap >= best_iou:
            best, best_iou = index, overlap
    return best


def coco_quality_report(predictor, coco_dir: Path, split: str | None = None) -> str:
    """``hkpd-eval --quality``'s tables: the shipped quality score against the error
    (:func:`hkpd.evaluation.quality_metrics.quality_table`) of the coco_mini people read
    through their annotated boxes and through the detector's own boxes."""
    parts = []
    for boxes in ("annotated", "detector"):
        readings = coco_readings(predictor, coco_dir, boxes, split=split)
        name = f"{coco_dir} {split or 'all splits'}, {boxes} boxes"
        if not readings:
            parts.append(f"Quality score on {name}: no readings")
            continue
        score = np.array([reading.score for reading in readings])
        error = np.array([reading.error for reading in readings])
        parts.append(quality_table(name, score, error))
    return "### Quality score against the error\n\n" + "\n\n".join(parts) + "\n"


def synthetic_readings(
    predictor, count: int, seed: int, show_progress: bool = True, batch: int = 16
) -> list[QualityReading]:
    """Readings of :func:`hard_synthetic_photos` (``count`` drawn with ``seed``); photos where
    the detector finds nobody or the truth shows < 6 keypoints are not scored."""
    readings = []
    progress = tqdm(total=count, disable=not show_progress, unit="photo")
    for start in range(0, count, batch):
        photos = hard_synthetic_photos(min(batch, count - start), seed * 100_003 + start)
        for index, photo in enumerate(photos):
            progress.update(1)
            if photo.visible.sum() < MIN_SCORED_KEYPOINTS:
                continue
            try:
                posterior = predictor.predict(photo.image, bbox=photo.search_box)
            except (NoPersonFoundError, ValueError):
                continue
            name = f"seed{seed}/{start + index}"
            readings.append(
                _reading("synthetic", name, posterior, photo.keypoints, photo.visible, photo.size)
            )
    progress.close()
    return readings


def hard_synthetic_photos(count: int, seed: int) -> list[SyntheticPhoto]:
    """``count`` synthetic photos with hard cases (module docstring), fully determined by
    ``seed``; in :data:`DISTRACTOR_PROBABILITY` of them a second rendered person stands
    beside the first, in front of or behind them, and the photo is read in the first person's
    search box (as coco_mini's annotated people are)."""
    config = SyntheticDataConfig(augmentation=HARD_AUGMENTATION, orientation=TRAINING_MIX)
    generator = SyntheticDataGenerator(pose_source(None, "val"), config, "cpu")
    rendered = generator.generate(count, seed)
    rng = np.random.default_rng(seed)
    torch_generator = torch.Generator().manual_seed(seed)
    backgrounds = generator.backgrounds.sample(count, torch_generator, CANVAS)
    layers = [
        _Layer(
            rendered.images[index],
            ((rendered.part_map[index] >= 0) | rendered.occluded[index]).numpy(),
            rendered.part_map[index].numpy() >= 0,
        )
        for index in range(count)
    ]
    photos = []
    for index in range(count):
        background = backgrounds[index].permute(1, 2, 0).mul(255).clamp(0, 255).byte().numpy()
        other = layers[(index + 1) % count] if count > 1 else None
        if rng.random() >= DISTRACTOR_PROBABILITY:
            other = None
        photos.append(
            _composed(
                np.ascontiguousarray(background), layers[index], other,
                rendered.batch.keypoints2d[index].double().numpy(),
                rendered.batch.visible[index].numpy(), rng,
            )
        )  # fmt: skip
    return photos


@dataclass(frozen=True)
class _Layer:
    """One rendered person: the ``(S, S, 3)`` render, the ``(S, S)`` pixels to paste (body and
    occluders) and the ``(S, S)`` body pixels."""

    render: np.ndarray
    paste: np.ndarray
    body: np.ndarray

    def placed(self, matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The render, paste mask and body mask moved onto the canvas by ``(2, 3)`` ``matrix``."""
        size = (CANVAS, CANVAS)
        warped = cv2.warpAffine(self.render, matrix, size, flags=cv2.INTER_LINEAR)
        paste = cv2.warpAffine(self.paste.astype(np.uint8), matrix, size) > 0
        body = cv2.warpAffine(self.body.astype(np.uint8), matrix, size) > 0
        return warped, paste, body


def _composed(
    canvas: np.ndarray,
    person: _Layer,
    other: _Layer | None,
    keypoints: np.ndarray,
    visible: np.ndarray,
    rng: np.random.Generator,
) -> SyntheticPhoto:
    """``person`` scaled and placed on ``canvas`` (perhaps cut off by its edge), ``other``
    (when given) beside it, in front or behind; then perhaps blurred and faded."""
    side = person.render.shape[0]
    scale = math.exp(rng.uniform(math.log(0.2), math.log(2.0)))
    scaled_side = max(round(side * scale), 8)
    reach = 0.45 * scaled_side if rng.random() < 0.35 else 0.0
    low, high = -reach, CANVAS - scaled_side + reach
    x0, y0 = (rng.uniform(min(low, high), max(low, high)) for _ in range(2))
    matrix = np.array([[scale, 0, x0], [0, scale, y0]], np.float64)
    warped, paste, body = person.placed(matrix)
    points = keypoints * scale + np.array([x0, y0])
    shown = np.asarray(visible, bool) & ((points >= 0) & (points <= CANVAS - 1)).all(-1)
    image = np.where(paste[..., None], warped, canvas)
    if other is not None:
        other_scale = scale * rng.uniform(0.7, 1.3)
        step = rng.choice([-1.0, 1.0]) * rng.uniform(0.25, 0.7) * scaled_side
        shift = np.array([x0 + step, y0 + rng.uniform(-0.2, 0.2) * scaled_side])
        other_matrix = np.array([[other_scale, 0, shift[0]], [0, other_scale, shift[1]]])
        other_warped, other_paste, _ = other.placed(other_matrix)
        if rng.random() < 0.5:  # in front: hides what it covers
            image = np.where(other_paste[..., None], other_warped, image)
            body &= ~other_paste
            pixels = np.clip(np.round(points).astype(np.int64), 0, CANVAS - 1)
            shown &= ~other_paste[pixels[:, 1], pixels[:, 0]]
        else:
            image = np.where(paste[..., None], warped, np.where(other_paste[..., None],
                             other_warped, canvas))  # fmt: skip
    rows, columns = np.nonzero(body)
    if not len(rows):
        return SyntheticPhoto(_degraded(image, rng), points, np.zeros_like(shown), 1.0)
    box = np.array([columns.min(), rows.min(), columns.max() + 1, rows.max() + 1], np.float64)
    size = float((box[2:] - box[:2]).max())
    search = None if other is None else box + 0.15 * size * np.array([-1, -1, 1, 1])
    return SyntheticPhoto(_degraded(image, rng), points, shown, size, search)


def _degraded(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Blur (30 %) and fade towards grey with noise (25 %): lower detector confidences."""
    result = image.astype(np.float32)
    if rng.random() < 0.3:
        result = cv2.GaussianBlur(result, (0, 0), rng.uniform(1.0, 3.5))
    if rng.random() < 0.25:
        contrast = rng.uniform(0.25, 0.6)
        result = 128 + (result - 128) * contrast + rng.normal(0, 8, result.shape)
    return np.clip(result + 0.5, 0, 255).astype(np.uint8)

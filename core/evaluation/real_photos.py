"""2D evaluation on real photos with human COCO keypoints (e.g. ``coco_mini``).

Each annotated person with enough visible keypoints goes through the full predictor (BlazePose
detection inside the person's annotated box, crop, proxy, network). The predicted mode and
samples are reprojected into the photo and compared with the human keypoints that are marked
visible (COCO ``v = 2``). Errors are reported in pixels of the network's crop rescaled to 256
(``error / crop side * 256``, comparable with the synthetic test set) and as a fraction of the
annotated box's larger side. For reference, the 2D detector's own keypoints (those it kept, at
confidence >= 0.6) are scored the same way: the network cannot be expected to beat its input
by much.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from tqdm import tqdm

from hkpd.camera_conventions import CROP_SIZE
from hkpd.evaluation.calibration import COVERAGE_LEVELS, point_truth_rank
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.image_input import ImageInputError
from hkpd.proxy import CONFIDENCE_THRESHOLD

MIN_VISIBLE_KEYPOINTS = 12
"""People with fewer visible keypoints are skipped ("mostly visible" people only)."""


@dataclass
class AnnotatedPerson:
    """One person of a COCO keypoint annotation file.

    Attributes:
        image_path: the photo.
        bbox: ``(x0, y0, x1, y1)`` annotated box, photo pixels.
        keypoints: ``(17, 2)`` human keypoints, photo pixels.
        visible: ``(17,)`` bool, COCO visibility flag 2.
        outlines: the annotated person mask as polygons, each ``(N, 2)`` photo pixels (COCO
            ``segmentation``); empty when the annotation has none.
        image_size: ``(width, height)`` of the photo, pixels (0, 0 when not known).
    """

    image_path: Path
    bbox: np.ndarray
    keypoints: np.ndarray
    visible: np.ndarray
    outlines: tuple[np.ndarray, ...] = ()
    image_size: tuple[int, int] = (0, 0)

    def search_box(self) -> np.ndarray:
        """``(4,)`` the annotated box grown by 15 % of its larger side on every edge: where the
        detector looks for this person (photo pixels)."""
        margin = 0.15 * float((self.bbox[2:] - self.bbox[:2]).max())
        return self.bbox + np.array([-margin, -margin, margin, margin])

    def silhouette(self) -> np.ndarray:
        """``(H, W)`` bool: the annotated person mask, drawn from :attr:`outlines`.

        Raises:
            ValueError: the annotation has no polygon mask or no photo size.
        """
        width, height = self.image_size
        if not self.outlines or width < 1 or height < 1:
            raise ValueError(f"{self.image_path}: this person has no polygon mask")
        mask = np.zeros((height, width), np.uint8)
        polygons = [np.round(outline).astype(np.int32) for outline in self.outlines]
        cv2.fillPoly(mask, polygons, 1)
        return mask.astype(bool)


def silhouette_argument(predictor, person: AnnotatedPerson) -> dict[str, np.ndarray]:
    """``predict``'s keyword arguments for ``person``'s mask: ``{"silhouette": mask}`` for a
    predictor whose network reads silhouettes, else none.

    Raises:
        ValueError: a silhouette network and a person without a polygon mask.
    """
    if getattr(predictor, "image_proxy", "edges") != "silhouette":
        return {}
    return {"silhouette": person.silhouette()}


def load_coco_people(
    coco_dir: Path, min_visible: int = MIN_VISIBLE_KEYPOINTS
) -> list[AnnotatedPerson]:
    """Every mostly-visible, non-crowd person of ``coco_dir/annotations/person_keypoints_*.json``
    whose photo exists in ``coco_dir/<split>/``.

    Raises:
        FileNotFoundError: no annotation file in ``coco_dir/annotations``.
    """
    files = sorted((Path(coco_dir) / "annotations").glob("person_keypoints_*.json"))
    if not files:
        raise FileNotFoundError(
            f"no COCO keypoint annotations (annotations/person_keypoints_*.json) in {coco_dir}"
        )
    people = []
    for annotation_file in files:
        split = annotation_file.stem.removeprefix("person_keypoints_")
        data = json.loads(annotation_file.read_text())
        names = {image["id"]: image["file_name"] for image in data["images"]}
        sizes = {image["id"]: (int(image.get("width", 0)), int(image.get("height", 0)))
                 for image in data["images"]}  # fmt: skip
        for annotation in data["annotations"]:
            values = np.asarray(annotation["keypoints"], dtype=np.float64).reshape(17, 3)
            visible = values[:, 2] == 2
            path = Path(coco_dir) / split / names[annotation["image_id"]]
            if annotation.get("iscrowd") or visible.sum() < min_visible or not path.is_file():
                continue
            x, y, w, h = annotation["bbox"]
            polygons = annotation.get("segmentation")
            outlines = tuple(
                np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
                for polygon in (polygons if isinstance(polygons, list) else [])
                if len(polygon) >= 6
            )
            box = np.array([x, y, x + w, y + h])
            size = sizes[annotation["image_id"]]
            people.append(AnnotatedPerson(path, box, values[:, :2], visible, outlines, size))
    return people


def _errors(
    points: torch.Tensor, person: AnnotatedPerson, kept: np.ndarray | None = None
) -> np.ndarray:
    """``(N, 17, 2)`` predicted photo pixels -> ``(N,)`` mean error over visible keypoints
    (and, if given, only those where the ``(17,)`` bool ``kept`` is True; NaN if none)."""
    target = torch.as_tensor(person.keypoints, dtype=points.dtype)
    scored = person.visible if kept is None else person.visible & kept
    if not scored.any():
        return np.full(points.shape[0], np.nan)
    distance = (points - target).norm(dim=-1)[:, torch.as_tensor(scored)]
    return distance.mean(-1).numpy()


def _keypoint_ranks(
    mode: torch.Tensor, samples: torch.Tensor, person: AnnotatedPerson
) -> torch.Tensor:
    """``(V,)`` ranks of the person's V visible annotated keypoints: ``mode`` ``(17, 2)`` and
    ``samples`` ``(S, 17, 2)`` photo pixels
    (:func:`hkpd.evaluation.calibration.point_truth_rank`)."""
    truth = torch.as_tensor(person.keypoints, dtype=torch.float64)
    ranks = point_truth_rank(mode.double(), samples.double(), truth)
    return ranks[torch.as_tensor(person.visible)]


def evaluate_photos(
    predictor, people: list[AnnotatedPerson], num_samples: int = 10, seed: int = 0,
    show_progress: bool = True, evidence: bool = False, upright: bool = False,
    mode_errors: list[float] | None = None, coverage_samples: int = 25,
) -> dict[str, float]:  # fmt: skip
    """Mean 2D errors of the mode and of samples over ``people``.

    Args:
        predictor: a :class:`hkpd.prediction.Predictor`.
        people: from :func:`load_coco_people`.
        num_samples: bodies sampled per person for the samples' error.
        evidence: score the keypoint-evidence posterior instead of the network's own.
        A network that reads silhouettes (the proxy ablation's) gets each person's annotated
        mask (:meth:`AnnotatedPerson.silhouette`); people without one count as failed.
        upright: let the network read people who lean more than 30° from an upright copy of
            the crop (``Predictor.predict``'s ``upright``; the predictor's default, off here so
            that the plain network is scored unless asked).
        coverage_samples: bodies sampled per person (a separate draw) for the 2D coverage.

    Returns:
        ``joint_error_2d_mode`` / ``joint_error_2d_samples`` (px at a 256 crop),
        ``..._box_fraction`` (fraction of the annotated box's larger side),
        ``joint_error_2d_detector`` (px at a 256 crop, the detector's kept keypoints), ``people``
        evaluated and ``failed`` (no detection); ``keypoint_coverage_2d_{50,90}``: share of the
        annotated keypoints (all people pooled) inside the disc about the mode's projection
        that holds 50 % / 90 % of the samples' projections
        (:func:`hkpd.evaluation.calibration.point_truth_rank`; calibrated:
        :func:`~hkpd.evaluation.calibration.calibrated_coverage`, 0.50 / 0.885 with 25 samples).
    """
    sums = {"mode": [], "samples": [], "mode_box": [], "samples_box": [], "detector": []}
    ranks: list[torch.Tensor] = []
    failed = 0
    for person in tqdm(people, disable=not show_progress, unit="person"):
        try:
            mask = silhouette_argument(predictor, person)
            posterior = predictor.predict(
                person.image_path, bbox=person.search_box(), evidence=evidence,
                upright=upright or evidence,
                **mask,
            )  # fmt: skip
        except (NoPersonFoundError, ImageInputError, ValueError):
            failed += 1
            if mode_errors is not None:
                mode_errors.append(math.nan)
            continue
        to_256 = CROP_SIZE / posterior.crop.side
        box_side = float((person.bbox[2:] - person.bbox[:2]).max())
        mode_points = posterior.mode().keypoints2d
        mode = _errors(mode_points, person)[0]
        samples = _errors(posterior.sample(num_samples, seed).keypoints2d, person).mean()
        sums["mode"].append(mode * to_256)
        if mode_errors is not None:
            mode_errors.append(float(mode * to_256))
        sums["samples"].append(samples * to_256)
        sums["mode_box"].append(mode / box_side)
        sums["samples_box"].append(samples / box_side)
        samples_points = posterior.sample(coverage_samples, seed + 1).keypoints2d
        ranks.append(_keypoint_ranks(mode_points[0], samples_points, person))
        kept = posterior.confidences.cpu().numpy() >= CONFIDENCE_THRESHOLD
        detector = _errors(posterior.keypoints.cpu()[None], person, kept)[0]
        if np.isfinite(detector):
            sums["detector"].append(detector * to_256)

    return _photo_summary(sums, ranks, failed)


def _photo_summary(
    sums: dict[str, list[float]], ranks: list[torch.Tensor], failed: int
) -> dict[str, float]:
    """:func:`evaluate_photos`' means of the per-person errors and pooled coverage."""

    def mean(values: list[float]) -> float:
        return float(np.mean(values)) if values else math.nan

    pooled = torch.cat(ranks) if ranks else torch.empty(0)
    return {
        "joint_error_2d_mode": mean(sums["mode"]),
        "joint_error_2d_samples": mean(sums["samples"]),
        "joint_error_2d_mode_box_fraction": mean(sums["mode_box"]),
        "joint_error_2d_samples_box_fraction": mean(sums["samples_box"]),
        "joint_error_2d_detector": mean(sums["detector"]),
        **{
            f"keypoint_coverage_2d_{round(level * 100)}": mean((pooled < level).tolist())
            for level in COVERAGE_LEVELS
        },
        "people": float(len(sums["mode"])),
        "failed": float(failed),
    }

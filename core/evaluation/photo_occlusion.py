"""Occlusion response on real photos: cover one annotated limb and see its uncertainty change.

For each person and each forearm / lower leg whose two annotated keypoints (elbow-wrist,
knee-ankle) are visible, a box around those keypoints (padded by 8 % of the person's box) is
given to the predictor as an occluder. The ratio of the limb's mean per-vertex uncertainty with
and without the box is the response; the other limbs' relative changes should stay small.
"""

from __future__ import annotations

import numpy as np
from tqdm import tqdm

from hkpd.evaluation.occlusion_response import OCCLUDED_LIMBS, limb_vertex_masks
from hkpd.evaluation.real_photos import AnnotatedPerson, silhouette_argument
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.image_input import ImageInputError

LIMB_KEYPOINTS = {
    "left_forearm": (7, 9),
    "right_forearm": (8, 10),
    "left_lower_leg": (13, 15),
    "right_lower_leg": (14, 16),
}
"""COCO keypoints (start, end) of each covered limb."""

PAD_FRACTION = 0.08


def limb_box(person: AnnotatedPerson, limb: str) -> tuple[float, float, float, float] | None:
    """``(x0, y0, x1, y1)`` around the limb's annotated keypoints, or None if one is hidden."""
    first, second = LIMB_KEYPOINTS[limb]
    if not (person.visible[first] and person.visible[second]):
        return None
    points = person.keypoints[[first, second]]
    pad = PAD_FRACTION * float((person.bbox[2:] - person.bbox[:2]).max())
    x0, y0 = points.min(0) - pad
    x1, y1 = points.max(0) + pad
    return (float(x0), float(y0), float(x1), float(y1))


def photo_occlusion_response(
    predictor,
    people: list[AnnotatedPerson],
    evidence: bool,
    samples: int = 100,
    show_progress: bool = True,
) -> dict[str, float]:
    """Median covered-limb ratio and the other limbs' median relative change.

    Args:
        predictor: a :class:`hkpd.prediction.Predictor` (a silhouette network gets each
            person's annotated mask, the box cleared from it).
        people: annotated people (:func:`hkpd.evaluation.real_photos.load_coco_people`).
        evidence: score the evidence posterior (else the network's own).
        samples: meshes per uncertainty.

    Returns:
        ``occlusion_ratio_median``, its quartiles, ``other_limbs_change_median`` and
        ``cases``.
    """
    masks = limb_vertex_masks(predictor.body)
    ratios: list[float] = []
    others: list[float] = []
    for person in tqdm(people, disable=not show_progress, unit="person"):
        search = person.search_box()
        try:
            mask = silhouette_argument(predictor, person)
            clean = predictor.predict(person.image_path, bbox=search, evidence=evidence, **mask)
        except (NoPersonFoundError, ImageInputError, ValueError):
            continue
        clean_u = clean.vertex_uncertainty(samples)
        for limb in OCCLUDED_LIMBS:
            box = limb_box(person, limb)
            if box is None:
                continue
            try:
                covered = predictor.predict(
                    person.image_path, occluders=[box], bbox=search, evidence=evidence, **mask
                )
            except (NoPersonFoundError, ImageInputError, ValueError):
                continue
            covered_u = covered.vertex_uncertainty(samples)
            ratios.append(float(covered_u[masks[limb]].mean() / clean_u[masks[limb]].mean()))
            for other in OCCLUDED_LIMBS:
                if other != limb:
                    before = clean_u[masks[other]].mean()
                    others.append(float((covered_u[masks[other]].mean() - before).abs() / before))
    if not ratios:
        return {"cases": 0.0}
    quartiles = np.percentile(ratios, [25, 50, 75])
    return {
        "occlusion_ratio_median": float(quartiles[1]),
        "occlusion_ratio_q25": float(quartiles[0]),
        "occlusion_ratio_q75": float(quartiles[2]),
        "other_limbs_change_median": float(np.median(others)),
        "cases": float(len(ratios)),
    }


__all__ = ["LIMB_KEYPOINTS", "limb_box", "photo_occlusion_response"]

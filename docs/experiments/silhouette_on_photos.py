"""Does the silhouette term help on real photos of a person alone? (docs/shape.md, section 5)

Every coco_mini person with >= 12 visible keypoints and a polygon mask (the people of
``hkpd-eval --shape --coco``), found by the detector in their box, is predicted by the shipped
predictor with keypoint evidence alone and with the person mask too. A person is *alone* when no
other annotated person (any number of visible keypoints) is in the photo. Per split and group:

- the mode's silhouette IoU against the COCO mask (:mod:`hkpd.evaluation.coco_silhouettes`),
  and the same with the average shape;
- BlazePose's own mask IoU;
- the mode's 2D keypoint error against the human keypoints (visible ones), as a fraction of the
  annotated box's larger side, and in photo pixels.

train2017 is the split for choosing (e.g. whether to fit the mask for people alone by default);
val2017 is held out.

    python docs/experiments/silhouette_on_photos.py --coco coco_mini
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.coco_silhouettes import person_silhouettes
from hkpd.evaluation.real_photos import AnnotatedPerson, load_coco_people
from hkpd.prediction import Predictor
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError

MIN_VISIBLE = 12
"""As ``hkpd-eval --shape --coco``."""


def keypoint_error(posterior: object, person: AnnotatedPerson) -> tuple[float, float]:
    """Mean distance of the mode's projected keypoints from the visible human keypoints: as a
    fraction of the annotated box's larger side, and in photo pixels."""
    projected = posterior.mode().keypoints2d[0].detach().cpu().numpy()
    distances = np.linalg.norm(projected - person.keypoints, axis=1)[person.visible]
    side = float((person.bbox[2:] - person.bbox[:2]).max())
    return float(distances.mean() / side), float(distances.mean())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--coco", type=Path, required=True)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    everyone = load_coco_people(args.coco, 0)
    per_photo = defaultdict(int)
    for person in everyone:
        per_photo[person.image_path] += 1
    people = [p for p in load_coco_people(args.coco, MIN_VISIBLE) if p.outlines]
    predictor = Predictor.from_pretrained(device="cpu")
    rows: dict[tuple[str, str, bool], list[tuple[float, ...]]] = defaultdict(list)
    for person in people:
        group = "alone" if per_photo[person.image_path] == 1 else "with others"
        for silhouette in (False, True):
            predictor.silhouette_evidence = silhouette
            try:
                posterior = predictor.predict(person.image_path, bbox=person.search_box())
            except (NoPersonFoundError, ValueError):
                break
            ious = person_silhouettes(posterior, person)
            error, pixels = keypoint_error(posterior, person)
            key = (person.image_path.parent.name, group, silhouette)
            rows[key].append(
                (ious.mode_iou, ious.average_shape_iou, ious.detector_iou or np.nan, error, pixels)
            )
    predictor.close()
    print("| split | people | evidence | mode IoU | average-shape IoU | BlazePose mask IoU | "
          "mode 2D error (box) | mode 2D error (px) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for (split, group, silhouette), values in sorted(rows.items()):
        mean = np.nanmean(np.array(values), axis=0)
        label = "keypoints + mask" if silhouette else "keypoints"
        print(f"| {split} | {group} ({len(values)}) | {label} | {mean[0]:.3f} | {mean[1]:.3f} | "
              f"{mean[2]:.3f} | {mean[3]:.4f} | {mean[4]:.1f} |")  # fmt: skip


if __name__ == "__main__":
    main()

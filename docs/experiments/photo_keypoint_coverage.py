"""Which keypoints does the posterior cover on real photos? Print evidence.md's per-keypoint table.

For every annotated person of a COCO folder (one split), the predictor's posterior, network
only and with the 2D evidence (both with the upright reading): per COCO keypoint, the share of
annotated keypoints inside the disc about the mode's projection that holds 50 % / 90 % of 25
sampled bodies' projections (:func:`hkpd.evaluation.calibration.point_truth_rank`; calibrated:
0.50 / 0.885), and the samples' median distance from the mode (px at a 256 crop). Then the
mode's and the detector's hips against the annotators', in the person's own frame (fractions
of the torso's length, median over people): is there a convention gap between the body model's
hip keypoints and COCO's?

    python docs/experiments/photo_keypoint_coverage.py assets/models/hkpd_hierarchical.pt \\
        --coco ../shared/data/coco_mini --coco-split train2017
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hkpd.camera_conventions import CROP_SIZE
from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.evaluation.calibration import point_truth_rank
from hkpd.evaluation.real_photos import AnnotatedPerson, load_coco_people
from hkpd.prediction.detection.keypoint_detector import NoPersonFoundError
from hkpd.prediction.image_input import ImageInputError
from hkpd.prediction.predictor import Predictor
from hkpd.proxy import CONFIDENCE_THRESHOLD

SAMPLES = 25
LEFT_SHOULDER, RIGHT_SHOULDER = (
    COCO17_NAMES.index("left_shoulder"),
    COCO17_NAMES.index("right_shoulder"),
)
LEFT_HIP, RIGHT_HIP = COCO17_NAMES.index("left_hip"), COCO17_NAMES.index("right_hip")


def hip_offsets(points: np.ndarray, person: AnnotatedPerson) -> np.ndarray | None:
    """``(2, 2)`` per hip (left, right): [outward, upward] offset of ``points`` (17, 2) from the
    annotated hips, in torso lengths; None unless both shoulders and hips are annotated."""
    truth = person.keypoints
    if not person.visible[[LEFT_SHOULDER, RIGHT_SHOULDER, LEFT_HIP, RIGHT_HIP]].all():
        return None
    mid_hip = (truth[LEFT_HIP] + truth[RIGHT_HIP]) / 2
    mid_shoulder = (truth[LEFT_SHOULDER] + truth[RIGHT_SHOULDER]) / 2
    torso = float(np.linalg.norm(mid_shoulder - mid_hip))
    up = (mid_shoulder - mid_hip) / torso
    across = truth[LEFT_HIP] - truth[RIGHT_HIP]
    across = across / np.linalg.norm(across)
    rows = []
    for joint, outward in ((LEFT_HIP, 1.0), (RIGHT_HIP, -1.0)):
        offset = (points[joint] - truth[joint]) / torso
        rows.append([outward * float(offset @ across), float(offset @ up)])
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--coco", type=Path, required=True)
    parser.add_argument("--coco-split", default="train2017")
    arguments = parser.parse_args()
    torch.set_num_threads(1)  # per-photo fits: one thread is the fast setting here

    people = [
        person
        for person in load_coco_people(arguments.coco)
        if person.image_path.parent.name == arguments.coco_split
    ]
    if not people:
        raise SystemExit(f"no annotated people in split {arguments.coco_split!r}")
    predictor = Predictor.from_pretrained(arguments.checkpoint)
    ranks = {label: [[] for _ in COCO17_NAMES] for label in ("network only", "2D evidence")}
    spreads: dict[str, list[np.ndarray]] = {label: [] for label in ranks}
    hips: dict[str, list[np.ndarray]] = {"network only": [], "2D evidence": [], "detector": []}
    for person in people:
        for label, evidence in (("network only", False), ("2D evidence", True)):
            try:
                posterior = predictor.predict(
                    person.image_path, bbox=person.search_box(), evidence=evidence, upright=True
                )
            except (NoPersonFoundError, ImageInputError, ValueError):
                continue
            mode = posterior.mode().keypoints2d[0].double()
            samples = posterior.sample(SAMPLES, 1).keypoints2d.double()
            truth = torch.as_tensor(person.keypoints, dtype=torch.float64)
            joint_ranks = point_truth_rank(mode, samples, truth)
            to_256 = CROP_SIZE / posterior.crop.side
            spread = (samples - mode).norm(dim=-1).median(0).values * to_256
            spreads[label].append(np.where(person.visible, spread.numpy(), np.nan))
            for joint in np.flatnonzero(person.visible):
                ranks[label][joint].append(float(joint_ranks[joint]))
            offsets = hip_offsets(mode.numpy(), person)
            if offsets is not None:
                hips[label].append(offsets)
            if evidence and offsets is not None:
                detected = posterior.keypoints.cpu().numpy().astype(np.float64)
                kept = posterior.confidences.cpu().numpy() >= CONFIDENCE_THRESHOLD
                detector = hip_offsets(detected, person)
                detector[~kept[[LEFT_HIP, RIGHT_HIP]]] = np.nan
                hips["detector"].append(detector)
    predictor.close()

    print(f"### Per-keypoint 2D coverage, {arguments.coco} {arguments.coco_split}\n")
    print(
        "| keypoint | n | network only: coverage 50 / 90 | spread (px) "
        "| 2D evidence: coverage 50 / 90 | spread (px) |"
    )
    print("|---|---|---|---|---|---|")
    median_spread = {label: np.nanmedian(np.stack(rows), axis=0) for label, rows in spreads.items()}
    for joint, name in enumerate(COCO17_NAMES):
        cells = []
        for label in ranks:
            values = np.array(ranks[label][joint])
            cells.append(f"{np.mean(values < 0.5):.2f} / {np.mean(values < 0.9):.2f}")
            cells.append(f"{median_spread[label][joint]:.1f}")
        print(f"| {name} | {len(ranks['2D evidence'][joint])} | " + " | ".join(cells) + " |")
    print("\n### Hips against the annotators' (torso lengths, median over people and hips)\n")
    print("| points | people | outward (+: wider) | upward (+: higher) |")
    print("|---|---|---|---|")
    names = {"network only": "mode, network only", "2D evidence": "mode, 2D evidence"}
    for label, rows in hips.items():
        stacked = np.stack(rows)
        outward, upward = np.nanmedian(stacked[..., 0]), np.nanmedian(stacked[..., 1])
        name = names.get(label, "BlazePose's keypoints")
        print(f"| {name} | {len(rows)} | {outward:+.3f} | {upward:+.3f} |")


if __name__ == "__main__":
    main()

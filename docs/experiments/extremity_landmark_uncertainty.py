"""Hands and feet with and without BlazePose's hand and foot landmarks as evidence
(docs/evidence.md, "Hand and foot landmarks").

For each photo, the shipped model's evidence posterior with the landmark term off and on
(``Predictor.landmark_evidence``): the mean per-vertex uncertainty (100 samples, seed 0) of the
body parts the issue tracks (forearm, hand, fingers, shin, foot, toes; the body model's part
labels: each joint's segment), per side, in cm; which of the side's landmarks were evidence;
then, with the landmarks on, a box over each hand and foot (the detected wrist or ankle and
that extremity's landmarks, padded by 6 % of the person box's longer side) and the covered
part's uncertainty ratio (covered / clear, hand + fingers or foot + toes); the hand's and foot's
spread about their wrist or ankle joint (:func:`about_joint`), off and on. Last, the time of
photo -> posterior + 100-sample uncertainty (median of ``--repeats``), both ways.

    python docs/experiments/extremity_landmark_uncertainty.py assets/photos/warrior_lunge.jpg \\
        ../shared/data/demo_photos/yogait_t5.jpg ../shared/data/demo_photos/yogait_test_y.jpg
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES
from hkpd.coco_keypoints import COCO17_NAMES
from hkpd.prediction import Predictor
from hkpd.prediction.posterior import BodyPosterior

PARTS = {
    "forearm": "elbow", "hand": "wrist", "fingers": "hand",
    "shin": "knee", "foot": "ankle", "toes": "foot",
}  # fmt: skip
"""Column name -> the body model's part label (``{side}_{label}``)."""

EXTREMITY = {
    "hand": ("wrist", ("pinky", "index", "thumb")),
    "foot": ("ankle", ("heel", "foot_index")),
}
COVERED_PARTS = {"hand": ("hand", "fingers"), "foot": ("foot", "toes")}
PAD = 0.06


def part_means(posterior: BodyPosterior, side: str) -> dict[str, float]:
    """Mean per-vertex uncertainty (cm) of each of :data:`PARTS` on ``side``."""
    spread = posterior.vertex_uncertainty(100, seed=0).cpu()
    body = posterior.body
    labels = body.part_labels.cpu()
    return {
        column: 100 * float(spread[labels == body.part_names.index(f"{side}_{label}")].mean())
        for column, label in PARTS.items()
    }


JOINT_OF = {"hand": "wrist", "fingers": "wrist", "foot": "ankle", "toes": "ankle"}
"""Column -> the joint its spread is also measured about."""


def about_joint(posterior: BodyPosterior, side: str) -> dict[str, float]:
    """Mean per-vertex spread (cm) of the hand, fingers, foot and toes on ``side`` about their
    wrist or ankle joint (each of 100 samples, seed 0, less its own joint position): the spread
    the hand's or foot's own turn leaves, without where the forearm or shin puts the joint."""
    drawn = posterior.sample(100, seed=0)
    body = posterior.body
    labels = body.part_labels.to(drawn.vertices.device)
    result = {}
    for column, joint in JOINT_OF.items():
        rows = labels == body.part_names.index(f"{side}_{PARTS[column]}")
        local = (
            drawn.vertices[:, rows]
            - drawn.joints[:, body.joint_names.index(f"{side}_{joint}")][:, None]
        )
        result[column] = 100 * float((local - local.mean(0)).norm(dim=-1).mean())
    return result


def extremity_box(posterior: BodyPosterior, side: str, kind: str) -> np.ndarray:
    """``(4,)`` box over one hand or foot's detected wrist/ankle and landmarks, photo pixels."""
    detection = posterior.network_input.detection
    joint, names = EXTREMITY[kind]
    points = [detection.keypoints[COCO17_NAMES.index(f"{side}_{joint}")]]
    points += [
        detection.extremities[BLAZEPOSE_EXTREMITY_NAMES.index(f"{side}_{name}")] for name in names
    ]
    points = np.asarray(points)
    box = detection.person_box
    pad = PAD * float(max(box[2] - box[0], box[3] - box[1]))
    return np.r_[points.min(0) - pad, points.max(0) + pad]


def shown(posterior: BodyPosterior, side: str) -> str:
    """Which of ``side``'s landmarks were evidence, e.g. ``pinky index - heel toe``."""
    mask = posterior.network_input.extremity_evidence
    names = [n for n in BLAZEPOSE_EXTREMITY_NAMES if n.startswith(side)]
    short = {"foot_index": "toe"}
    words = []
    for name in names:
        word = short.get(name.split("_", 1)[1], name.split("_", 1)[1])
        words.append(word if mask[BLAZEPOSE_EXTREMITY_NAMES.index(name)] else "-")
    return " ".join(words)


def covered_ratios(predictor: Predictor, photo: str, posterior: BodyPosterior) -> list[str]:
    """Table rows: each hand's and foot's uncertainty ratio (covered / clear) under a box
    (:func:`extremity_box` on ``posterior``'s detection), the landmarks off and on."""
    ratios: dict[tuple[str, str], list[float]] = {}
    for landmarks in (False, True):
        predictor.landmark_evidence = landmarks
        clear = predictor.predict(photo)
        for side in ("left", "right"):
            for kind, parts in COVERED_PARTS.items():
                box = extremity_box(posterior, side, kind)
                covered = part_means(predictor.predict(photo, occluders=[box]), side)
                before = part_means(clear, side)
                ratio = sum(covered[p] for p in parts) / sum(before[p] for p in parts)
                ratios.setdefault((side, kind), []).append(ratio)
    name = Path(photo).name
    return [f"| {name} | {side} {kind} | {off:.2f} | {on:.2f} |"
            for (side, kind), (off, on) in ratios.items()]  # fmt: skip


def timed(predictor: Predictor, photo: str, repeats: int) -> float:
    """Median seconds of predict + 100-sample vertex uncertainty."""
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        predictor.predict(photo).vertex_uncertainty(100, seed=0)
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", nargs="+")
    parser.add_argument("--repeats", type=int, default=7, help="0: no timing")
    args = parser.parse_args()
    torch.set_grad_enabled(False)
    predictor = Predictor.from_pretrained()
    columns = " | ".join(PARTS)
    print(f"| photo | side | landmarks | shown | {columns} |")
    print("|---|---|---|---|" + "---|" * len(PARTS))
    covered_rows, timing_rows, joint_rows = [], [], []
    for photo in args.photos:
        name = Path(photo).name
        for landmarks in (False, True):
            predictor.landmark_evidence = landmarks
            posterior = predictor.predict(photo)
            for side in ("left", "right"):
                values = " | ".join(f"{v:.1f}" for v in part_means(posterior, side).values())
                print(f"| {name} | {side} | {'on' if landmarks else 'off'} | "
                      f"{shown(posterior, side)} | {values} |")  # fmt: skip
                local = " | ".join(f"{v:.1f}" for v in about_joint(posterior, side).values())
                joint_rows.append(f"| {name} | {side} | {'on' if landmarks else 'off'} | {local} |")
        covered_rows += covered_ratios(predictor, photo, posterior)
        for landmarks in (False, True) if args.repeats else ():
            predictor.landmark_evidence = landmarks
            timing_rows.append(f"| {name} | {'on' if landmarks else 'off'} | "
                               f"{1000 * timed(predictor, photo, args.repeats):.0f} |")  # fmt: skip
    print(
        "\n| photo | side | landmarks | "
        + " | ".join(f"{c} about its {j}" for c, j in JOINT_OF.items())
        + " |"
    )
    print("|---|---|---|" + "---|" * len(JOINT_OF))
    print("\n".join(joint_rows))
    print("\n| photo | box over | ratio covered / clear, landmarks off | landmarks on |")
    print("|---|---|---|---|")
    print("\n".join(covered_rows))
    print("\n| photo | landmarks | photo -> posterior + 100-sample uncertainty, median ms |")
    print("|---|---|---|")
    print("\n".join(timing_rows))


if __name__ == "__main__":
    main()

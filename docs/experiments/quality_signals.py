"""Which cheap signals tell a bad reading on real photos? (issue 51's quality score, a baseline)

Every coco_mini person with >= 6 visible keypoints is read by the shipped predictor in their
annotated box grown by 15 % (as ``hkpd-eval --coco`` does). A reading is *off* when the mode's
2D keypoints are on average more than 0.2 of the annotated box's larger side from the human
keypoints (visible ones). Printed per split: the AUROC with which each signal alone ranks the
off readings below the rest, and a small logistic rule fitted on train2017 (L2, standardised
signals) scored on val2017.

    python docs/experiments/quality_signals.py path/to/coco_mini
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.quality_metrics import auroc
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.prediction import NoPersonFoundError, Predictor

OFF = 0.2
SIGNALS = ("mean_confidence", "downweighted_share", "at_edge", "box_height", "evidence_share",
           "cost_per_keypoint", "mirror_read")  # fmt: skip


def signals(posterior) -> list[float]:
    """The signals of one reading (higher is not always better; see the table)."""
    detection = posterior.network_input.detection
    width, height = detection.image_size
    box = np.asarray(detection.person_box, float)
    fit = posterior.evidence_fit
    shown = max(int(posterior.evidence.sum()), 1)
    weights = fit.keypoint_weights if fit is not None and fit.keypoint_weights is not None else None
    low = 0 if weights is None else int((weights[posterior.evidence.bool()] < 0.5).sum())
    edge = min(box[0], box[1], width - box[2], height - box[3]) / max(width, height)
    return [
        float(posterior.confidences.mean()), low / shown, float(edge < 0.01),
        float((box[3] - box[1]) / height), shown / 17,
        (fit.cost / shown) if fit is not None and fit.conditioned is not None else 10.0,
        float(posterior.mirror_read),
    ]  # fmt: skip


def logistic(features: np.ndarray, good: np.ndarray, penalty: float = 1.0) -> np.ndarray:
    """Weights (bias first) of an L2-penalised logistic regression, by Newton steps."""
    design = np.c_[np.ones(len(features)), features]
    weights = np.zeros(design.shape[1])
    ridge = penalty * np.diag(np.r_[0.0, np.ones(design.shape[1] - 1)])
    for _ in range(50):
        p = 1 / (1 + np.exp(-design @ weights))
        gradient = design.T @ (p - good) + ridge @ weights
        hessian = design.T @ (design * (p * (1 - p))[:, None]) + ridge
        weights -= np.linalg.solve(hessian, gradient)
    return weights


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    rows = {"train2017": [], "val2017": []}
    for person in load_coco_people(args.coco, min_visible=6):
        split = person.image_path.parent.name
        try:
            posterior = predictor.predict(person.image_path, bbox=person.search_box())
        except (NoPersonFoundError, ValueError, OSError):  # nobody found: not scored
            continue
        mode = posterior.mode().keypoints2d[0].numpy()
        size = float((person.bbox[2:] - person.bbox[:2]).max())
        seen = person.visible
        error = float(np.linalg.norm(mode[seen] - person.keypoints[seen], axis=1).mean() / size)
        rows.setdefault(split, []).append((signals(posterior), error))
    predictor.close()
    train = rows["train2017"]
    features = np.array([s for s, _ in train])
    mean, spread = features.mean(0), features.std(0) + 1e-9
    weights = logistic((features - mean) / spread, np.array([e <= OFF for _, e in train], float))
    print("| split | readings | off | " + " | ".join(SIGNALS) + " | rule |")
    print("|---" * (len(SIGNALS) + 4) + "|")
    for split, items in rows.items():
        values = np.array([s for s, _ in items])
        off = np.array([e > OFF for _, e in items])
        rule = np.c_[np.ones(len(values)), (values - mean) / spread] @ weights
        cells = [auroc(values[:, i], off) for i in range(len(SIGNALS))] + [auroc(rule, off)]
        print(f"| {split} | {len(items)} | {int(off.sum())} | "
              + " | ".join(f"{c:.2f}" for c in cells) + " |")  # fmt: skip


if __name__ == "__main__":
    main()

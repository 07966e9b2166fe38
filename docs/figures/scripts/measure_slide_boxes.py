"""Measure how much a box over a part of the shipped CC0 photo changes what the explorer shows,
to choose the docs' slide example (docs/explorer.md): for each candidate box (built around
detected keypoints, padded by a quarter of the limb), the keypoints that stay evidence and the
mean vertex uncertainty (cm, 100 samples, seed 0) of the parts the box covers, without and with
the box.

    python docs/figures/scripts/measure_slide_boxes.py [--box X0 Y0 X1 Y1]...
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.posterior_view import part_uncertainty
from hkpd.prediction import BodyPosterior, Predictor, load_image

COCO_INDEX = {"left_elbow": 7, "right_elbow": 8, "left_wrist": 9, "right_wrist": 10,
              "left_hip": 11, "right_hip": 12, "left_knee": 13, "right_knee": 14,
              "left_ankle": 15, "right_ankle": 16}  # fmt: skip
CANDIDATES: dict[str, tuple[str, ...]] = {
    "right shin (knee + ankle)": ("right_knee", "right_ankle"),
    "left shin (knee + ankle)": ("left_knee", "left_ankle"),
    "right leg (hip + knee + ankle)": ("right_hip", "right_knee", "right_ankle"),
    "left leg (hip + knee + ankle)": ("left_hip", "left_knee", "left_ankle"),
    "left forearm (elbow + wrist)": ("left_elbow", "left_wrist"),
    "right forearm (elbow + wrist)": ("right_elbow", "right_wrist"),
}
"""Candidate boxes: the keypoints each box is drawn around."""
PARTS = {"right shin": "right_knee", "left shin": "left_knee", "right thigh": "right_hip",
         "left thigh": "left_hip", "left forearm": "left_elbow", "right forearm": "right_elbow",
         "left hand": "left_wrist", "right hand": "right_wrist"}  # fmt: skip
"""Part name in the docs -> the SMPL part (the vertices that joint moves most)."""


def box_around(posterior: BodyPosterior, names: tuple[str, ...]) -> tuple[int, int, int, int]:
    """A box (photo pixels, integers) around the keypoints ``names``, padded by a quarter of
    their largest distance (as the lessons' shin box)."""
    points = posterior.keypoints.numpy()[[COCO_INDEX[name] for name in names]]
    pad = 0.25 * float(np.ptp(points, axis=0).max())
    low, high = points.min(0) - pad, points.max(0) + pad
    return tuple(int(v) for v in (*np.round(low), *np.round(high)))  # type: ignore[return-value]


def parts_cm(posterior: BodyPosterior) -> dict[str, float]:
    """Mean vertex uncertainty (cm, 100 samples, seed 0) of each of :data:`PARTS`."""
    parts = part_uncertainty(
        posterior.vertex_uncertainty(100, seed=0).numpy(), posterior.body.part_labels.numpy()
    )
    return {name: 100 * parts[part] for name, part in PARTS.items()}


def evidence_count(posterior: BodyPosterior) -> int:
    fit = posterior.evidence_fit
    return fit.evidence_count if posterior.conditioned and fit is not None else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--box", nargs=4, type=float, action="append", default=[],
                        metavar=("X0", "Y0", "X1", "Y1"), help="also measure this box")  # fmt: skip
    args = parser.parse_args()
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    photo = load_image(shipped_photo()).pixels
    plain = predictor.predict(photo)
    before = parts_cm(plain)
    print(f"no box ({evidence_count(plain)} keypoints as evidence): "
          + ", ".join(f"{k} {v:.1f}" for k, v in before.items()))  # fmt: skip
    boxes = {name: box_around(plain, names) for name, names in CANDIDATES.items()}
    boxes |= {f"given {tuple(box)}": tuple(box) for box in args.box}
    print("| box | X0 Y0 X1 Y1 | keypoints as evidence | part: without -> with the box, cm |")
    print("|---|---|---:|---|")
    for name, box in boxes.items():
        after = parts_cm(predictor.predict(photo, occluders=[box]))
        changed = sorted(after, key=lambda part: before[part] - after[part])[:3]
        evidence = evidence_count(predictor.predict(photo, occluders=[box]))
        moved = "; ".join(f"{p} {before[p]:.1f} -> {after[p]:.1f}" for p in changed)
        print(f"| {name} | {' '.join(str(round(v)) for v in box)} | {evidence} | {moved} |")


if __name__ == "__main__":
    main()

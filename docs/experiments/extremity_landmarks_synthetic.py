"""Hand and foot vertex error and uncertainty on synthetic test views, with and without the
landmark term (docs/evidence.md, "Hand and foot landmarks").

Synthetic examples (procedural poses or a pose bank's ``test`` split, the evaluation's crops)
are read by the shipped network; their exact keypoints get detector-like noise
(:func:`detector_like_keypoints`) and their exact hand and foot landmarks (the body model's
regressors, projected by the example's camera) get the landmarks' own
(:func:`detector_like_extremities`; a hand's landmarks count as shown when its wrist keypoint
is visible, a foot's with its ankle). Each example is fitted as the predictor fits a photo, with
the keypoints alone and with the landmark term too. Per body part (hand, fingers, foot, toes:
the model's ``*_wrist``, ``*_hand``, ``*_ankle``, ``*_foot`` parts, both sides), root-aligned in
the camera frame: the mode's mean vertex error, the samples' mean per-vertex uncertainty
(``--samples``), and the share of vertices whose truth lies within the samples' 90 % distance
from their mean (the samples' own share is 0.9 by construction).

    python docs/experiments/extremity_landmarks_synthetic.py --count 64 [--poses poses.npz]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES, extremity_landmarks
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, condition_on_keypoints
from hkpd.conditioning.landmark_term import LandmarkConfig, LandmarkEvidence, LandmarkTerm
from hkpd.distributions import BodyDistribution
from hkpd.network.checkpoint import load_network
from hkpd.poses import pose_source
from hkpd.prediction.predictor import float64_body, shipped_model_path
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.detector_noise import (
    DetectorNoise,
    detector_like_extremities,
    detector_like_keypoints,
)
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

PARTS = {"hand": "wrist", "fingers": "hand", "foot": "ankle", "toes": "foot"}
SHOWN_BY = (9, 10, 9, 10, 9, 10, 15, 16, 15, 16)
"""COCO keypoint whose visibility stands for each extremity landmark's (wrist, ankle)."""


def true_landmarks(body, batch, regressor) -> torch.Tensor:
    """``(B, 10, 2)`` the examples' exact landmarks in the keypoints' pixels: perspective
    projection of the true mesh, mapped by the per-example scale and offset that takes the
    projected keypoints onto ``batch.keypoints2d`` (least squares)."""
    posed = body(batch.betas, batch.body_pose, batch.global_orient)
    origin = posed.joints[:, :1] - batch.joints3d[:, :1]
    points = torch.cat((posed.keypoints, regressor.of_mesh(posed.vertices)), 1) - origin
    plane = batch.focal_px[:, None, None] * points[..., :2] / points[..., 2:]
    keypoints, target = plane[:, :17], batch.keypoints2d
    centred = keypoints - keypoints.mean(1, keepdim=True)
    scale = (centred * (target - target.mean(1, keepdim=True))).sum((1, 2)) / centred.square().sum(
        (1, 2)
    )
    offset = target.mean(1) - scale[:, None] * keypoints.mean(1)
    mapped = scale[:, None, None] * keypoints + offset[:, None]
    misfit = float((mapped - target).norm(dim=-1).max())
    print(f"keypoints through the recovered camera: worst misfit {misfit:.3f} px")
    return scale[:, None, None] * plane[:, 17:] + offset[:, None]


def part_metrics(body, fitted: BodyDistribution, batch, item: int, samples: int) -> dict:
    """Mode error, uncertainty and 90 % coverage per part (metres, share) of one example."""
    generator = torch.Generator().manual_seed(item)
    pose = fitted.pose_distribution().sample(samples, generator=generator).float()
    pose = pose.reshape(samples, 23, 3, 3)
    mode_pose = fitted.pose_distribution().mode.float()
    betas = fitted.shape_mean.float().reshape(1, -1)
    noise = torch.randn(samples, betas.shape[1], generator=generator)
    sample_betas = betas + noise * fitted.shape_std.float().reshape(1, -1)
    orient = fitted.global_orient.float().reshape(1, 3, 3)

    def centred(b, p):
        out = body(b, p, orient.expand(b.shape[0], 3, 3))
        return out.vertices - out.joints[:, :1]

    mode = centred(betas, mode_pose.reshape(1, 23, 3, 3))[0]
    drawn = centred(sample_betas, pose)
    truth_out = body(batch.betas[item : item + 1], batch.body_pose[item : item + 1],
                     batch.global_orient[item : item + 1])  # fmt: skip
    truth = (truth_out.vertices - truth_out.joints[:, :1])[0]
    mean = drawn.mean(0)
    spread = (drawn - mean).norm(dim=-1)
    radius90 = spread.quantile(0.9, dim=0)
    inside = (truth - mean).norm(dim=-1) <= radius90
    result = {}
    for column, label in PARTS.items():
        rows = torch.zeros_like(body.part_labels, dtype=torch.bool)
        for side in ("left", "right"):
            rows |= body.part_labels == body.part_names.index(f"{side}_{label}")
        result[column] = (
            float((mode - truth)[rows].norm(dim=-1).mean()),
            float(spread[:, rows].mean()),
            float(inside[rows].float().mean()),
        )
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=64)
    parser.add_argument("--samples", type=int, default=50)
    parser.add_argument("--poses", type=Path, default=None)
    parser.add_argument(
        "--seed", type=int, default=2021, help="2021: the test views; another to choose settings"
    )
    parser.add_argument("--hand-sigma-scale", type=float, default=LandmarkConfig.hand_sigma_scale)
    parser.add_argument("--foot-sigma-scale", type=float, default=LandmarkConfig.foot_sigma_scale)
    args = parser.parse_args()
    landmark_config = LandmarkConfig(args.hand_sigma_scale, args.foot_sigma_scale)
    torch.set_grad_enabled(False)
    network, _ = load_network(shipped_model_path(), "cpu")
    network.eval()
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size),
        image_proxy=network.config.image_proxy,
        augmentation=AugmentationConfig.disabled(),
    )
    synthetic = SyntheticDataGenerator(pose_source(args.poses, "test"), config, "cpu")
    body, body64 = synthetic.body, float64_body(synthetic.body)
    regressor = extremity_landmarks(body).rows(BLAZEPOSE_EXTREMITY_NAMES)
    regressor64 = extremity_landmarks(body64).rows(BLAZEPOSE_EXTREMITY_NAMES)
    evidence_config = EvidenceConfig()
    batch = synthetic.generate(args.count, seed=args.seed).batch
    size = batch.proxy.shape[-1]
    output = network(batch.proxy)
    noise = torch.Generator().manual_seed(0)
    detected, reported = detector_like_keypoints(
        batch.keypoints2d, batch.visible, size, DetectorNoise(), noise
    )
    exact = true_landmarks(body, batch, regressor)
    shown = batch.visible[:, list(SHOWN_BY)]
    landmarks, landmark_reported = detector_like_extremities(exact, shown, size, noise)
    totals = {name: {c: [] for c in PARTS} for name in ("keypoints", "keypoints + landmarks")}
    for item in range(args.count):
        start = output.rows(slice(item, item + 1)).to(torch.float64)
        evidence = KeypointEvidence(detected[item].double(), reported[item], size)
        term = LandmarkTerm(
            LandmarkEvidence(landmarks[item].double(), landmark_reported[item], size),
            regressor64, evidence_config.keypoint_sigma, evidence_config.robust_scale,
            landmark_config,
        )  # fmt: skip
        for name, terms in (("keypoints", []), ("keypoints + landmarks", [term])):
            fit = condition_on_keypoints(body64, start, evidence, evidence_config, terms)
            fitted = start.rows(0) if fit.conditioned is None else fit.conditioned
            for column, values in part_metrics(body, fitted, batch, item, args.samples).items():
                totals[name][column].append(values)
    print(f"{args.count} synthetic examples ({size} px), {args.samples} samples each, "
          f"{landmark_config}\n")  # fmt: skip
    print("| evidence | part | mode error cm | uncertainty cm | truth within 90 % radius |")
    print("|---|---|---|---|---|")
    for name, columns in totals.items():
        for column, rows in columns.items():
            values = torch.tensor(rows)
            error, spread, inside = values.mean(0).tolist()
            print(f"| {name} | {column} | {100 * error:.1f} | {100 * spread:.1f} | {inside:.2f} |")


if __name__ == "__main__":
    main()

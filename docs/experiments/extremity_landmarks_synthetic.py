"""Hand and foot vertex error, uncertainty and calibration on synthetic views, with and
without the landmark term (docs/evidence.md, "Hand and foot landmarks").

Synthetic examples (procedural poses or a pose bank's ``test`` split, no augmentation) are read
by the shipped network and scored by :func:`hkpd.evaluation.extremity_eval.
evaluate_extremity_batches` (``hkpd-eval --extremities`` scores the fixed test set the same
way): detector-like noise on the keypoints and on the hand and foot landmarks, each example
fitted with the keypoints alone and with the landmark term too; per part (hand, fingers, foot,
toes) the mode's vertex error, the samples' uncertainty (also about the wrist or ankle joint),
50 % / 90 % coverage, and the wrists' and ankles' rotation error and spread.

    python docs/experiments/extremity_landmarks_synthetic.py --count 48 [--poses poses.npz]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.conditioning.landmark_term import LandmarkConfig
from hkpd.evaluation.extremity_eval import evaluate_extremity_batches, extremity_markdown
from hkpd.network.checkpoint import load_network
from hkpd.poses import pose_source
from hkpd.prediction.predictor import shipped_model_path
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator


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
    batch = synthetic.generate(args.count, seed=args.seed).batch
    record = evaluate_extremity_batches(
        network, [batch], synthetic.body, EvidenceConfig(), landmark_config, args.samples
    )
    print(f"keypoints through the recovered camera: worst misfit "
          f"{record['landmark_misfit_px']:.3f} px")  # fmt: skip
    print(extremity_markdown(record, f"{args.count} synthetic examples "
                             f"({config.image_size} px), {args.samples} samples each, "
                             f"seed {args.seed}, {landmark_config}"))  # fmt: skip


if __name__ == "__main__":
    main()

"""The silhouette term's weights against masks that err as BlazePose's do (docs/shape.md §2).

The term's sigmas were chosen on validation examples with a lighter mask degradation than the
one measured for BlazePose since (docs/shape.md section 3). This script scores, on the pose
bank's ``val`` subjects (never the test set), the evidence posterior's shape with keypoints
alone and with the mask at several settings of :class:`hkpd.conditioning.SilhouetteConfig`,
the masks made by today's :class:`hkpd.synthesis.mask_noise.MaskNoise` defaults: R² of β₀ and
mean over β₁…β₉, PVE-T-SC (mm) and z² per coefficient (1: honest; the issue asks 0.6-1.6).

    python docs/experiments/silhouette_sigmas_measured_masks.py CHECKPOINT --poses poses.npz \\
        --count 150
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from hkpd.conditioning import SilhouetteConfig
from hkpd.evaluation.shape_eval import (
    evaluate_shape_batches,
    rendered_test_set,
    silhouette_terms_for,
)
from hkpd.evaluation.test_set import network_and_generator, stored_evidence_settings
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader

VALIDATION_SEED = 77
"""Seed of the validation examples (the test set's is 2021, on other subjects)."""

SETTINGS = {
    "defaults (σ 0.02 / 0.04 / 0.1, margin 0.02)": SilhouetteConfig(),
    "σ × 1.5": SilhouetteConfig(outside_sigma=0.03, inside_sigma=0.06, boundary_sigma=0.15),
    "σ × 2": SilhouetteConfig(outside_sigma=0.04, inside_sigma=0.08, boundary_sigma=0.2),
    "σ × 1.5, margin 0.01": SilhouetteConfig(
        outside_sigma=0.03, inside_sigma=0.06, boundary_sigma=0.15, inside_margin=0.01
    ),
}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--poses", type=Path)
    parser.add_argument("--count", type=int, default=150)
    args = parser.parse_args(argv)
    network, generator = network_and_generator(args.checkpoint, args.poses, "cpu", split="val")
    reader = ProxyReader(network, ReadingConfig(mirror=True), upright=False, body=generator.body)
    posteriors = {
        name: silhouette_terms_for(generator.body, config) for name, config in SETTINGS.items()
    }
    with torch.no_grad():
        scores = evaluate_shape_batches(
            reader, rendered_test_set(generator, args.count, VALIDATION_SEED), generator.body,
            evidence=True, config=stored_evidence_settings(args.checkpoint),
            more_evidence=posteriors,
        )  # fmt: skip
    print("| evidence | R² β₀ | mean R² β₁…β₉ | R² β₁, β₂ | PVE-T-SC mm | z² β₀ | z² β₁…β₉ |")
    print("|---|---|---|---|---|---|---|")
    for name, score in scores.items():
        r2, z2 = score.r2, score.z2
        print(f"| {name} | {r2[0]:.3f} | {sum(r2[1:]) / 9:.3f} | {r2[1]:.2f}, {r2[2]:.2f} | "
              f"{score.pve_t_sc_mm:.2f} | {z2[0]:.2f} | "
              f"{', '.join(f'{value:.2f}' for value in z2[1:])} |")  # fmt: skip


if __name__ == "__main__":
    main()

"""What one silhouette can tell about each shape coefficient (docs/shape.md, section 2).

1. **Outline move per unit.** A seeded test body (the one of ``tests/test_silhouette_term.py``,
   seed 3), frontal and turned 90°, rasterised exactly at a 256 crop with a weak-perspective
   camera; for each coefficient ``k`` the silhouette of ``β = e_k`` against ``β = 0``: changed
   pixels / outline pixels, the mean move of the outline in pixels per unit.
2. **Fits with the pose given.** Six seeded bodies (seeds 3-8), their exact masks and keypoints;
   the fit starts at the true pose (concentration 1e4) and camera with the mean shape, so only
   the shape is left to the evidence. Mean |Δβ| over β₁…β₉, per coefficient, and PVE-T-SC, for
   keypoints only and the silhouette term at a few settings.

    python docs/experiments/silhouette_observability.py
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import (
    EvidenceConfig,
    KeypointEvidence,
    SilhouetteConfig,
    SilhouetteEvidence,
    SilhouetteTerm,
    SurfaceSamples,
    condition_on_keypoints,
)
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.metrics import pve_t_sc_from_betas

SIZE = 256
CAMERA = torch.tensor([0.9, 0.0, 0.1], dtype=torch.float64)
EXACT = SilhouetteConfig(
    outside_sigma=0.01, inside_sigma=0.02, boundary_sigma=0.05, inside_margin=0.0
)
TIGHT = replace(EXACT, outside_sigma=0.004, inside_sigma=0.008, boundary_sigma=0.02)


@dataclass(frozen=True)
class Body:
    """A seeded pose (23 relative rotations, 0.2 rad noise) and shape (standard normal)."""

    pose: torch.Tensor
    betas: torch.Tensor

    @classmethod
    def seeded(cls, seed: int) -> Body:
        generator = torch.Generator().manual_seed(seed)
        pose = roma.rotvec_to_rotmat(0.2 * torch.randn(23, 3, generator=generator).double())
        return cls(pose, torch.randn(1, 10, generator=generator).double())


def crop_pixels(body: BodyModel, betas: torch.Tensor, pose: torch.Tensor, orient: torch.Tensor):
    """``(V, 2)`` vertex and ``(17, 2)`` keypoint pixels through :data:`CAMERA`."""
    output = body(betas, pose[None], orient[None])
    root = output.joints[0, :1]

    def project(points: torch.Tensor) -> torch.Tensor:
        return ndc_to_pixels(CAMERA[0] * ((points - root)[:, :2] + CAMERA[1:]), SIZE)

    return project(output.vertices[0]), project(output.keypoints[0])


def silhouette(body: BodyModel, vertex_pixels: torch.Tensor) -> np.ndarray:
    """``(S, S)`` uint8 exact silhouette (faces rasterised at 1/16 px)."""
    mask = np.zeros((SIZE, SIZE), np.uint8)
    for triangle in np.round(vertex_pixels.numpy()[body.faces.numpy()] * 16).astype(np.int32):
        cv2.fillConvexPoly(mask, triangle, 1, cv2.LINE_8, 4)
    return mask


def outline_moves(body: BodyModel) -> None:
    case = Body.seeded(3)
    turn = roma.rotvec_to_rotmat(torch.tensor([0.0, np.pi / 2, 0.0], dtype=torch.float64))
    print("| view | outline px | " + " | ".join(f"β{k}" for k in range(10)) + " |")
    print("|---" * 12 + "|")
    for view, orient in (("front", FRONTAL_GLOBAL_ORIENT.double()),
                         ("side", turn @ FRONTAL_GLOBAL_ORIENT.double())):  # fmt: skip
        base = silhouette(
            body, crop_pixels(body, torch.zeros(1, 10).double(), case.pose, orient)[0]
        )
        outline = int((base - cv2.erode(base, np.ones((3, 3), np.uint8))).sum())
        moves = []
        for k in range(10):
            betas = torch.zeros(1, 10, dtype=torch.float64)
            betas[0, k] = 1.0
            changed = silhouette(body, crop_pixels(body, betas, case.pose, orient)[0]) != base
            moves.append(f"{changed.sum() / outline:.2f}")
        print(f"| {view} | {outline} | " + " | ".join(moves) + " |")


def given_pose_fits(body: BodyModel) -> None:
    orient = FRONTAL_GLOBAL_ORIENT.double()
    cases = []
    for seed in range(3, 9):
        case = Body.seeded(seed)
        vertices, keypoints = crop_pixels(body, case.betas, case.pose, orient)
        start = BodyDistribution(
            F=(1e4 * case.pose)[None],
            shape_mean=torch.zeros(1, 10, dtype=torch.float64),
            shape_std=torch.ones(1, 10, dtype=torch.float64),
            global_orient=orient[None],
            camera=CAMERA[None].clone(),
        )
        evidence = KeypointEvidence(keypoints, torch.ones(17, dtype=torch.bool), SIZE)
        cases.append((case, start, evidence, silhouette(body, vertices)))
    rows = {
        "keypoints only": None,
        "exact-mask settings, 400 points": (EXACT, 400),
        "tight sigmas, 400 points": (TIGHT, 400),
        "tight sigmas, 1000 points, 300 boundary points": (
            replace(TIGHT, boundary_points=300),
            1000,
        ),
    }
    print("\n| fit (pose and camera given) | mean |Δβ₁…₉| | per coefficient | PVE-T-SC mm |")
    print("|---|---|---|---|")
    for name, setting in rows.items():
        surface = None if setting is None else SurfaceSamples.of(body, setting[1])
        errors, pves = [], []
        for case, start, evidence, mask in cases:
            terms = []
            if setting is not None:
                mask_evidence = SilhouetteEvidence.from_arrays(mask.astype(np.float64), None)
                terms = [SilhouetteTerm(mask_evidence, surface, setting[0])]
            fit = condition_on_keypoints(body, start, evidence, EvidenceConfig(), terms)
            predicted = fit.conditioned.shape_mean[None]
            errors.append((predicted - case.betas)[0].abs())
            pves.append(float(pve_t_sc_from_betas(body, predicted, case.betas)[0]))
        error = torch.stack(errors)
        per_coefficient = np.round(error.mean(0).numpy(), 2).tolist()
        print(f"| {name} | {float(error[:, 1:].mean()):.2f} | {per_coefficient} | "
              f"{1000 * np.mean(pves):.2f} |")  # fmt: skip


def main() -> None:
    torch.set_num_threads(1)
    body = BodyModel().double()
    outline_moves(body)
    given_pose_fits(body)


if __name__ == "__main__":
    main()

"""The silhouette term on synthetic *validation* examples: keypoints only vs keypoints + mask.

For ``--count`` validation examples (the pose bank's ``val`` subjects) the shipped network reads
the example, detector-like keypoints (:mod:`hkpd.synthesis.detector_noise`) are the keypoint
evidence, and the body's exact silhouette (the renderer's part map, perspective camera) is the
mask, as it is or degraded (dilated for clothing and hair, its boundary blurred, then jittered
by a smooth random field). Each row fits with keypoints only or keypoints + silhouette, and
builds the Laplace posterior with the global rotation and camera held fixed (``conditional``),
marginalised for the shape (``shape``) or for the shape and the joints (``marginal``). It
prints, per row: R² of the shape mean (β₀; mean over β₁…β₉), PVE-T-SC (mm), z² (mean of (pred −
true)²/std²: β₀, and min/max over β₁…β₉), the mode's MPJPE-PA (mm) and 2D keypoint error (px at
256), the pose coverage (share of joints whose true rotation lies in the 50 % / 90 % region of
25 samples: 0.5 / 0.9 is calibrated), and the median fit time (ms).

    .venv/bin/python docs/experiments/silhouette_term_validation.py --count 100

Results and how the settings were chosen: ``docs/shape.md``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path

import cv2
import numpy as np
import torch

from hkpd.body import BodyModel
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
from hkpd.evaluation.prediction_metrics import EvaluationTargets, evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.evaluation.test_set import network_and_generator
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints

ROOT = Path(__file__).resolve().parents[2]
MASKS = ("exact", "dilated", "detector-like")


@dataclass(frozen=True)
class Example:
    """One validation example: the network's output row, the evidence and the truth."""

    start: BodyDistribution
    keypoints: KeypointEvidence
    masks: dict[str, np.ndarray]
    index: int


def degraded_mask(exact: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    """``(S, S)`` float probability: the exact mask, or dilated by 3 px and blurred (σ 1.5 px),
    or that with its boundary moved by a smooth random field (±2 px) like a detector's."""
    if kind == "exact":
        return exact.astype(np.float64)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    grown = cv2.dilate(exact.astype(np.uint8), disc).astype(np.float64)
    if kind == "detector-like":
        size = exact.shape[0]
        field = cv2.resize(rng.normal(size=(8, 8)), (size, size), interpolation=cv2.INTER_CUBIC)
        outside = cv2.distanceTransform((1 - grown).astype(np.uint8), cv2.DIST_L2, 5)
        inside = cv2.distanceTransform(grown.astype(np.uint8), cv2.DIST_L2, 5)
        grown = ((inside - outside) + 2.0 * field > 0).astype(np.float64)
    return cv2.GaussianBlur(grown, (0, 0), 1.5)


def load_examples(
    count: int, checkpoint: Path, poses: Path, seed: int
) -> tuple[list[Example], EvaluationTargets]:
    """``count`` validation examples with their network outputs and evidence, and their truth."""
    network, generator = network_and_generator(checkpoint, poses, "cpu", split="val")
    noise_generator = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    examples: list[Example] = []
    targets: list[EvaluationTargets] = []
    batch_index = 0
    while len(examples) < count:
        rendered = generator.generate(min(16, count - len(examples)), seed + batch_index)
        batch = rendered.batch
        size = batch.proxy.shape[-1]
        with torch.no_grad():
            output = network(batch.proxy)
        detected, reported = detector_like_keypoints(
            batch.keypoints2d, batch.visible, size, DetectorNoise(), noise_generator
        )
        exact_masks = (rendered.part_map >= 0).cpu().numpy()
        for item in range(batch.proxy.shape[0]):
            examples.append(
                Example(
                    start=output.rows(slice(item, item + 1)).detach().to(torch.float64),
                    keypoints=KeypointEvidence(detected[item], reported[item], size),
                    masks={kind: degraded_mask(exact_masks[item], kind, rng) for kind in MASKS},
                    index=len(examples),
                )
            )
        batch_index += 1
        targets.append(targets_of(batch))
    joined = {
        field.name: torch.cat([getattr(t, field.name) for t in targets])
        for field in fields(EvaluationTargets)
    }
    return examples, EvaluationTargets(**joined)


def run_row(
    examples: list[Example],
    body64: BodyModel,
    config: EvidenceConfig,
    mask: str | None,
    silhouette: SilhouetteConfig,
) -> tuple[BodyDistribution, list[float]]:
    """The posterior of every example (the network's where the fit falls back) and fit times."""
    rows, seconds = [], []
    surface = SurfaceSamples.of(body64)
    for example in examples:
        terms = []
        if mask is not None:
            evidence = SilhouetteEvidence.from_arrays(example.masks[mask], None)
            terms = [SilhouetteTerm(evidence, surface, silhouette)]
        began = time.perf_counter()
        fit = condition_on_keypoints(body64, example.start, example.keypoints, config, terms)
        seconds.append(time.perf_counter() - began)
        chosen = fit.conditioned.map(lambda t: t[None]) if fit.succeeded else example.start
        rows.append(chosen)
    stacked = BodyDistribution(
        *(torch.cat(parts) for parts in zip(*(r.tensors() for r in rows), strict=True))
    )
    return stacked, seconds


def scores(
    posterior: BodyDistribution, truth: EvaluationTargets, body: BodyModel, crop_size: int
) -> dict[str, np.ndarray | float]:
    """R², z² per coefficient, PVE-T-SC and pose errors of a posterior against the truth."""
    true_betas = truth.betas.double()
    error = posterior.shape_mean.double() - true_betas
    r2 = 1.0 - error.var(0) / true_betas.var(0)
    z2 = (error / posterior.shape_std.double()).square().mean(0)
    pve = pve_t_sc_from_betas(body, posterior.shape_mean.float(), truth.betas.float())
    generator = torch.Generator().manual_seed(0)
    metrics = evaluate_prediction(
        posterior.to(torch.float32), body, truth, 25, crop_size, generator
    )
    return {
        "r2": r2.numpy(),
        "z2": z2.numpy(),
        "pve_t_sc_mm": 1000.0 * float(pve.mean()),
        "mpjpe_pa_mm": 1000.0 * float(metrics["mpjpe_pa"].mean()),
        "error_2d_px": float(metrics["joint_error_2d_mode"].nanmean()) * 256.0 / crop_size,
        "coverage": (
            float(metrics["pose_coverage_50"].nanmean()),
            float(metrics["pose_coverage_90"].nanmean()),
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument(
        "--checkpoint", type=Path, default=ROOT / "assets/models/hkpd_hierarchical.pt"
    )
    parser.add_argument("--poses", type=Path, default=Path("/work/data/poses.npz"))
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--masks", nargs="*", default=list(MASKS))
    parser.add_argument(
        "--sigmas",
        nargs=3,
        type=float,
        default=None,
        metavar=("OUTSIDE", "INSIDE", "BOUNDARY"),
        help="silhouette sigmas (fractions of the crop side); default SilhouetteConfig()'s",
    )
    parser.add_argument("--inside-margin", type=float, default=None)
    args = parser.parse_args()
    torch.set_num_threads(1)
    silhouette = SilhouetteConfig()
    if args.sigmas is not None:
        outside, inside, boundary = args.sigmas
        silhouette = replace(
            silhouette, outside_sigma=outside, inside_sigma=inside, boundary_sigma=boundary
        )
    if args.inside_margin is not None:
        silhouette = replace(silhouette, inside_margin=args.inside_margin)
    examples, truth = load_examples(args.count, args.checkpoint, args.poses, args.seed)
    body = BodyModel()
    body64 = BodyModel().double()
    print(f"{len(examples)} validation examples; silhouette {silhouette}")
    columns = "mask | laplace | R² β₀ | R² β₁…₉ | PVE-T-SC mm | z² β₀ | z² β₁…₉ | MPJPE-PA mm"
    print(f"| {columns} | 2D px | pose coverage 50/90 | fit ms |")
    print("|" + "---|" * 11)
    for mask in (None, *args.masks):
        for rigid in ("conditional", "shape", "marginal"):
            config = replace(EvidenceConfig(), rigid_spread=rigid)
            posterior, seconds = run_row(examples, body64, config, mask, silhouette)
            s = scores(posterior, truth, body, examples[0].keypoints.crop_size)
            r2, z2 = s["r2"], s["z2"]
            print(
                f"| {mask or 'keypoints only'} | {rigid} | {r2[0]:.2f} | {r2[1:].mean():.2f} | "
                f"{s['pve_t_sc_mm']:.2f} | {z2[0]:.2f} | {z2[1:].min():.2f}–{z2[1:].max():.2f} | "
                f"{s['mpjpe_pa_mm']:.1f} | {s['error_2d_px']:.2f} | "
                f"{s['coverage'][0]:.3f} / {s['coverage'][1]:.3f} | "
                f"{1000 * np.median(seconds):.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()

"""How much shape do explicit mask widths carry? (docs/shape.md, section 4, "ways forward")

Synthetic examples of the pose bank's ``train`` subjects (``edges+mask`` generator at
``--image-size``: the rendered silhouette, its detector-like degraded version as the network
would read it, and the keypoints drawn into the heatmaps). Per example, **width features**:

- for each limb segment (upper arms, forearms, thighs, shins) and at 1/4, 1/2 and 3/4 of its
  length, the mask's width across the segment (pixels at probability ≥ 0.5 along the
  perpendicular through that point, sampled every 1/4 pixel up to one segment length each way),
  divided by the segment's length;
- the torso's width across at the shoulders, the middle and the hips, over its length;
- the segments' lengths over the torso's length (proportions).

Ridge regressions (5-fold cross-validation, features standardised, regularisation chosen by
generalised cross-validation on each training fold) from those features to each β give the R²
that such features could carry to a shape head: with the degraded mask, with the exact
silhouette, and from the proportions alone (keypoints only). Examples where a segment's
keypoints are hidden or leave the crop keep NaN features, filled with the training folds'
means. It is a bound on what a small head reading these numbers could learn, not a network.

    python docs/experiments/mask_width_features.py --poses poses.npz --count 3000
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hkpd.poses import pose_source
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

SEGMENTS = ((5, 7), (7, 9), (6, 8), (8, 10), (11, 13), (13, 15), (12, 14), (14, 16))
"""COCO-17 keypoint pairs: left/right upper arm, forearm; left/right thigh, shin."""

FRACTIONS = (0.25, 0.5, 0.75)
MASK_CHANNEL = 1


def width_across(mask: np.ndarray, point: np.ndarray, normal: np.ndarray, reach: float) -> float:
    """Pixels of ``mask (S, S)`` (≥ 0.5, nearest sample) along ``point ± t · normal``,
    ``|t| ≤ reach``, counted from ``point`` outwards until the first background sample each way."""
    size = mask.shape[0]
    steps = np.arange(0.0, reach, 0.25)
    total = 0.0
    for sign in (1.0, -1.0):
        samples = point + sign * steps[:, None] * normal
        columns = np.clip(np.round(samples[:, 0]).astype(int), 0, size - 1)
        rows = np.clip(np.round(samples[:, 1]).astype(int), 0, size - 1)
        inside = mask[rows, columns] >= 0.5
        outside = np.flatnonzero(~inside)
        total += (outside[0] if outside.size else steps.size) * 0.25
    return total


def features(mask: np.ndarray, keypoints: np.ndarray, present: np.ndarray) -> np.ndarray:
    """Width and proportion features of one example (NaN where keypoints are missing)."""
    shoulders = (keypoints[5] + keypoints[6]) / 2
    hips = (keypoints[11] + keypoints[12]) / 2
    torso = float(np.linalg.norm(shoulders - hips))
    torso_ok = present[[5, 6, 11, 12]].all() and torso > 2.0
    values: list[float] = []
    lengths: list[float] = []
    for first, second in SEGMENTS:
        start, end = keypoints[first], keypoints[second]
        length = float(np.linalg.norm(end - start))
        usable = present[first] and present[second] and length > 2.0
        direction = (end - start) / max(length, 1e-9)
        normal = np.array([-direction[1], direction[0]])
        for fraction in FRACTIONS:
            point = start + fraction * (end - start)
            width = width_across(mask, point, normal, length) if usable else np.nan
            values.append(width / length if usable else np.nan)
        lengths.append(length / torso if usable and torso_ok else np.nan)
    axis = (shoulders - hips) / max(torso, 1e-9)
    across = np.array([-axis[1], axis[0]])
    for fraction in (0.0, 0.5, 1.0):
        point = hips + fraction * (shoulders - hips)
        width = width_across(mask, point, across, torso) if torso_ok else np.nan
        values.append(width / torso if torso_ok else np.nan)
    return np.array(values + lengths)


def cross_validated_r2(x: np.ndarray, y: np.ndarray, folds: int = 5) -> np.ndarray:
    """``(K,)`` R² of ridge regressions from ``x (N, F)`` to each column of ``y (N, K)``."""
    order = np.random.default_rng(0).permutation(len(x))
    predicted = np.zeros_like(y)
    for fold in range(folds):
        test = order[fold::folds]
        train = np.setdiff1d(order, test)
        mean = np.nanmean(x[train], axis=0)
        filled = np.where(np.isnan(x), mean, x)
        scale = filled[train].std(0) + 1e-9
        standard = (filled - mean) / scale
        a, b = standard[train], y[train]
        y_mean = b.mean(0)
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        best = None
        for alpha in 10.0 ** np.arange(-3, 4):  # generalised cross-validation per fold
            shrink = s / (s**2 + alpha)
            fit = a @ (vt.T @ (shrink[:, None] * (u.T @ (b - y_mean))))
            dof = float((s**2 / (s**2 + alpha)).sum())
            gcv = ((b - y_mean - fit) ** 2).mean(0) / (1 - dof / len(a)) ** 2
            if best is None or gcv.mean() < best[0]:
                best = (gcv.mean(), alpha)
        shrink = s / (s**2 + best[1])
        weights = vt.T @ (shrink[:, None] * (u.T @ (b - y_mean)))
        predicted[test] = standard[test] @ weights + y_mean
    return 1.0 - ((predicted - y) ** 2).mean(0) / y.var(0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=Path, required=True)
    parser.add_argument("--count", type=int, default=3000)
    parser.add_argument("--image-size", type=int, default=128)
    args = parser.parse_args()
    torch.set_num_threads(2)
    config = SyntheticDataConfig(image_size=args.image_size, image_proxy="edges+mask")
    generator = SyntheticDataGenerator(pose_source(args.poses, "train"), config, "cpu")
    rows: dict[str, list[np.ndarray]] = {"degraded": [], "exact": []}
    betas = []
    for index in range(0, args.count, 50):
        rendered = generator.generate(min(50, args.count - index), 1000 + index)
        batch = rendered.batch
        keypoints = rendered.input_keypoints.numpy()
        present = rendered.input_present.numpy()
        exact = ((rendered.part_map >= 0) & ~rendered.occluded).numpy().astype(np.float64)
        degraded = batch.proxy[:, MASK_CHANNEL].numpy()
        for item in range(keypoints.shape[0]):
            rows["exact"].append(features(exact[item], keypoints[item], present[item]))
            rows["degraded"].append(features(degraded[item], keypoints[item], present[item]))
        betas.append(batch.betas.numpy())
    y = np.concatenate(betas).astype(np.float64)
    proportions = slice(len(SEGMENTS) * len(FRACTIONS) + 3, None)
    print(f"{len(y)} training-subject examples at {args.image_size} px")
    print("| features | " + " | ".join(f"R² β{k}" for k in range(10)) + " | mean β₁…β₉ |")
    print("|---" * 12 + "|")
    exact, degraded = np.stack(rows["exact"]), np.stack(rows["degraded"])
    for name, x in (("proportions only (keypoints)", exact[:, proportions]),
                    ("widths + proportions, degraded mask", degraded),
                    ("widths + proportions, exact silhouette", exact)):  # fmt: skip
        r2 = cross_validated_r2(x, y)
        print(f"| {name} | " + " | ".join(f"{v:.2f}" for v in r2) + f" | {r2[1:].mean():.3f} |")


if __name__ == "__main__":
    main()

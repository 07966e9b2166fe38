"""How far BlazePose puts its hand and foot landmarks from the body model's, on synthetic renders
(docs/evidence.md, "Hand and foot landmarks": the landmark term's sigmas).

Synthetic people (procedural poses or a pose bank's ``val`` split; no augmentation: a person in
full view on a background) are rendered at 256 pixels and shown to BlazePose
(:class:`KeypointDetector`). For every point the render shows (depth test, as the training
data's keypoint visibility) and BlazePose reports with visibility >= 0.6, the error against the
body model's point projected by the render's camera (the COCO-17 regressor's keypoints; the
landmark regressors of :mod:`hkpd.body.extremity_landmarks`), per group (COCO keypoints, hand
landmarks, foot landmarks): the median distance, the robust per-coordinate sigma (1.4826 × MAD
of the coordinate errors about their median), the mean offset along the limb, and the share of
outliers (further than 20 % of the crop). The keypoints' row is the reference: the landmark
term's sigmas are the keypoint sigma times each group's sigma ratio to it.

    python docs/experiments/extremity_landmark_noise.py --count 120 [--poses poses.npz]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES, extremity_landmarks
from hkpd.poses import pose_source
from hkpd.prediction import KeypointDetector, NoPersonFoundError
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator
from hkpd.synthesis.visibility import keypoint_visibility

CONFIDENT = 0.6
OUTLIER = 0.2
GROUPS = {
    "COCO keypoints (17)": None, "hand landmarks (6)": range(6), "foot landmarks (4)": range(6, 10),
}  # fmt: skip
LANDMARK_DEPTH_TOLERANCE = 0.05
"""A landmark (inside a finger or toe) counts as shown when no surface lies more than this many
metres in front of it."""


def rendered_points(count: int, seed: int, poses: Path | None):
    """Images, true 2D points ``(B, 27, 2)`` (17 keypoints, then the 10 extremities, crop
    pixels) and their visibility ``(B, 27)``."""
    config = SyntheticDataConfig(augmentation=AugmentationConfig.disabled())
    generator_ = SyntheticDataGenerator(pose_source(poses, "val"), config, "cpu")
    regressor = extremity_landmarks(generator_.body).rows(BLAZEPOSE_EXTREMITY_NAMES)
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        scene = generator_._draw_scene(count, generator, None)
        camera = generator_._draw_crop_camera(scene, generator)
        rendered, image, part_map, occluded = generator_._render(scene, camera, generator)
    points3d = torch.cat((scene.keypoints3d, regressor.of_mesh(scene.vertices)), 1)
    points = camera.project(points3d)
    keypoints = points[:, :17]
    visible = keypoint_visibility(
        keypoints, points3d[:, :17, 2], rendered.depth, part_map, occluded
    )
    visible = torch.cat(
        (visible, landmark_shown(points[:, 17:], points3d[:, 17:, 2], rendered.depth)), 1
    )
    images = image.mul(255).add(0.5).clamp(0, 255).to(torch.uint8).permute(0, 2, 3, 1).numpy()
    return np.ascontiguousarray(images), points.double().numpy(), visible.numpy()


def landmark_shown(points: torch.Tensor, depth: torch.Tensor, depth_map: torch.Tensor):
    """``(B, L)`` bool: inside the crop and no surface more than
    :data:`LANDMARK_DEPTH_TOLERANCE` in front."""
    count, height, width = depth_map.shape
    pixel = points.round().long()
    inside = (pixel >= 0).all(-1) & (pixel[..., 0] < width) & (pixel[..., 1] < height)
    flat = pixel[..., 1].clamp(0, height - 1) * width + pixel[..., 0].clamp(0, width - 1)
    surface = depth_map.reshape(count, -1).gather(1, flat)
    return inside & (surface >= depth - LANDMARK_DEPTH_TOLERANCE)


def detected_points(images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """BlazePose's ``(B, 27, 2)`` points and ``(B, 27)`` confidences (NaN when nobody found)."""
    points = np.full((len(images), 27, 2), np.nan)
    confidences = np.zeros((len(images), 27))
    with KeypointDetector(segmentation=False) as detector:
        for index, image in enumerate(images):
            try:
                found = detector.detect(image)
            except NoPersonFoundError:
                continue
            points[index] = np.concatenate([found.keypoints, found.extremities])
            confidences[index] = np.concatenate([found.confidences, found.extremity_confidences])
    return points, confidences


def summary(errors: np.ndarray, size: int) -> str:
    """One table row's numbers from ``(M, 2)`` coordinate errors, pixels."""
    distance = np.linalg.norm(errors, axis=1)
    inlier = distance <= OUTLIER * size
    kept = errors[inlier]
    mad = np.median(np.abs(kept - np.median(kept, 0)), 0).mean()
    sigma = 1.4826 * mad
    return (f"{len(errors)} | {np.median(distance):.1f} | {sigma:.2f} | "
            f"{sigma / size:.4f} | {100 * (1 - inlier.mean()):.1f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=120)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--poses", type=Path, default=None)
    args = parser.parse_args()
    images, truth, visible = rendered_points(args.count, args.seed, args.poses)
    found, confidence = detected_points(images)
    size = images.shape[1]
    use = visible & (confidence >= CONFIDENT) & np.isfinite(found).all(-1)
    errors = found - truth
    print(f"{args.count} renders, {int(np.isfinite(found[:, 0, 0]).sum())} with a person found\n")
    print("| points | scored | median px | sigma px | sigma / crop side | outliers % |")
    print("|---|---|---|---|---|---|")
    for name, rows in GROUPS.items():
        columns = np.arange(17) if rows is None else 17 + np.array(list(rows))
        print(f"| {name} | {summary(errors[:, columns][use[:, columns]], size)} |")
    print("\n| landmark | scored | median px | sigma px | sigma / crop side | outliers % |")
    print("|---|---|---|---|---|---|")
    for index, name in enumerate(BLAZEPOSE_EXTREMITY_NAMES):
        column = 17 + index
        print(f"| {name} | {summary(errors[:, column][use[:, column]], size)} |")


if __name__ == "__main__":
    main()

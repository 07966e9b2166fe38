"""All metrics for one batch of network predictions: the building block of ``hkpd-eval``.

:func:`evaluate_prediction` poses the predicted mode body and ``num_samples`` bodies sampled from
the predicted distributions, and returns per-example metrics (see :mod:`hkpd.evaluation.metrics`
for the definitions). Targets that a dataset lacks (e.g. 3D joints for in-the-wild photos) are
None, and the metrics that need them are left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.body.body_model import BodyModel
from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import CROP_SIZE, ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.calibration import rotation_coverage
from hkpd.evaluation.metrics import (
    MIN_OF_N_COUNTS,
    joint_error_2d,
    min_of_n,
    mpjpe,
    mpjpe_procrustes,
    mpjpe_scale_corrected,
    pve_t_sc,
    sample_diversity,
)

SAMPLES_FOR_2D_ERROR = 10
"""The paper's "2D Joint Err. Samples" uses 10 sampled bodies per image."""


@dataclass
class EvaluationTargets:
    """Ground truth for a batch; any field may be None when the dataset lacks it.

    Attributes:
        joints3d: ``(B, 24, 3)`` SMPL-order joints, metres, in the camera frame (any frame
            whose orientation matches the predicted ``global_orient`` works for MPJPE; -SC and
            -PA are frame-independent).
        betas: ``(B, K)`` shape coefficients, for PVE-T-SC.
        keypoints2d: ``(B, 17, 2)`` COCO keypoints in crop pixels.
        visible: ``(B, 17)`` bool, which ``keypoints2d`` are visible (needed with them).
        body_pose: ``(B, 23, 3, 3)`` true relative joint rotations, for the coverage of the
            pose distribution (:mod:`hkpd.evaluation.calibration`).
    """

    joints3d: torch.Tensor | None = None
    betas: torch.Tensor | None = None
    keypoints2d: torch.Tensor | None = None
    visible: torch.Tensor | None = None
    body_pose: torch.Tensor | None = None


@torch.no_grad()
def evaluate_prediction(
    output: BodyDistribution,
    body: BodyModel,
    targets: EvaluationTargets,
    num_samples: int = 25,
    crop_size: int = CROP_SIZE,
    generator: torch.Generator | None = None,
) -> dict[str, torch.Tensor]:
    """Per-example metrics of a batch of predictions.

    Args:
        output: the network's prediction.
        body: body model (same device and dtype).
        targets: ground truth; metrics whose targets are None are skipped.
        num_samples: S bodies sampled per example, for min-of-N (N in
            :data:`MIN_OF_N_COUNTS` up to S), the samples' 2D error (first 10) and diversity.
            0 skips every sample metric.
        crop_size: pixel size of the crops ``keypoints2d`` refer to.
        generator: optional random generator for the samples.

    Returns:
        ``{name: (B,)}``, 3D metrics in metres, 2D errors in pixels, with names
        ``mpjpe``, ``mpjpe_sc``, ``mpjpe_pa``, ``pve_t_sc``, ``joint_error_2d_mode``,
        ``joint_error_2d_samples``, ``joint_spread_2d_samples`` (the samples' mean 2D
        distance from the mode's keypoints, on the visible joints: with Gaussian-like errors a
        calibrated model has ``samples error ≈ sqrt(mode error² + spread²)``),
        ``{mpjpe,mpjpe_pa,pve_t_sc}_min_of_{N}``,
        ``diversity_visible`` and ``diversity_invisible`` (3D COCO keypoint spread), and
        ``pose_coverage_{50,90}`` (share of joints whose true rotation lies in the 50% / 90%
        most probable region, ranked among the S samples; needs ``targets.body_pose``).
    """
    if targets.keypoints2d is not None and targets.visible is None:
        raise ValueError("targets.keypoints2d needs targets.visible (use all-True if unknown)")
    pose = output.pose_distribution()
    keypoints, joints = pelvis_relative_body(
        body, output.shape_mean, pose.mode, output.global_orient
    )
    projection = _Projection(output.camera, crop_size)
    target_tpose = None if targets.betas is None else body.tpose(targets.betas)
    results = _mode_metrics(output, body, targets, keypoints, joints, target_tpose, projection)
    if num_samples < 1:
        return results
    poses = pose.sample(num_samples, generator=generator)
    betas = output.sample_betas(num_samples, generator)
    if targets.body_pose is not None:
        for level, share in rotation_coverage(output.F, poses, targets.body_pose).items():
            results[f"pose_coverage_{round(level * 100)}"] = share
    stacked, per_sample = _sample_bodies(output, body, targets, target_tpose, poses, betas)
    counts = [n for n in MIN_OF_N_COUNTS if n <= num_samples]
    for name, values in per_sample.items():
        if values:
            for n, value in min_of_n(torch.stack(values), counts).items():
                results[f"{name}_min_of_{n}"] = value
    if targets.keypoints2d is not None:
        first = stacked[: min(SAMPLES_FOR_2D_ERROR, num_samples)]
        projected = torch.stack([projection(points) for points in first])
        results["joint_error_2d_samples"] = joint_error_2d(
            projected, targets.keypoints2d, targets.visible
        )
        results["joint_spread_2d_samples"] = joint_error_2d(
            projected, projection(keypoints), targets.visible
        )
    visible = (
        targets.visible.bool()
        if targets.visible is not None
        else torch.ones(stacked.shape[1:3], dtype=torch.bool, device=stacked.device)
    )
    diversity = sample_diversity(stacked, visible)
    results["diversity_visible"] = diversity["visible"]
    results["diversity_invisible"] = diversity["invisible"]
    return results


@dataclass(frozen=True)
class _Projection:
    """Pelvis-relative camera-frame points ``(..., 17, 3)`` to crop pixels ``(..., 17, 2)``
    through the predicted weak-perspective camera."""

    camera: torch.Tensor
    crop_size: int

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        return ndc_to_pixels(weak_perspective_project(points, self.camera), self.crop_size)


def _mode_metrics(
    output: BodyDistribution,
    body: BodyModel,
    targets: EvaluationTargets,
    keypoints: torch.Tensor,
    joints: torch.Tensor,
    target_tpose: torch.Tensor | None,
    projection: _Projection,
) -> dict[str, torch.Tensor]:
    """The mode body's metrics: MPJPE (plain, -SC, -PA), PVE-T-SC and the 2D mode error."""
    results: dict[str, torch.Tensor] = {}
    if targets.joints3d is not None:
        results["mpjpe"] = mpjpe(joints, targets.joints3d)
        results["mpjpe_sc"] = mpjpe_scale_corrected(joints, targets.joints3d)
        results["mpjpe_pa"] = mpjpe_procrustes(joints, targets.joints3d)
    if target_tpose is not None:
        results["pve_t_sc"] = pve_t_sc(body.tpose(output.shape_mean), target_tpose)
    if targets.keypoints2d is not None:
        results["joint_error_2d_mode"] = joint_error_2d(
            projection(keypoints), targets.keypoints2d, targets.visible
        )
    return results


def _sample_bodies(
    output: BodyDistribution,
    body: BodyModel,
    targets: EvaluationTargets,
    target_tpose: torch.Tensor | None,
    poses: torch.Tensor,
    betas: torch.Tensor,
) -> tuple[torch.Tensor, dict[str, list[torch.Tensor]]]:
    """The sampled bodies' ``(S, B, 17, 3)`` keypoints and their per-sample 3D errors
    (``mpjpe``, ``mpjpe_pa``, ``pve_t_sc``: S ``(B,)`` values each, where targets allow)."""
    per_sample: dict[str, list[torch.Tensor]] = {"mpjpe": [], "mpjpe_pa": [], "pve_t_sc": []}
    sample_keypoints = []
    for index in range(poses.shape[0]):  # one sample per pass keeps the memory bounded
        sample_kp, sample_joints = pelvis_relative_body(
            body, betas[index], poses[index], output.global_orient
        )
        sample_keypoints.append(sample_kp)
        if targets.joints3d is not None:
            per_sample["mpjpe"].append(mpjpe(sample_joints, targets.joints3d))
            per_sample["mpjpe_pa"].append(mpjpe_procrustes(sample_joints, targets.joints3d))
        if target_tpose is not None:
            per_sample["pve_t_sc"].append(pve_t_sc(body.tpose(betas[index]), target_tpose))
    return torch.stack(sample_keypoints), per_sample

"""The training losses of the paper's Section 3.4, as pure functions.

Conventions (see :mod:`hkpd.camera_conventions`):

- Bodies are posed with the predicted (or sampled) shape, relative joint rotations and global
  rotation, *without* translation, and made **pelvis-relative** by subtracting the posed pelvis
  joint (SMPL joint 0). The weak-perspective camera ``[s, tx, ty]`` acts on these points:
  ``ndc = s * (X_xy + t)``.
- 2D targets are the batch's ``keypoints2d`` (crop pixels) converted to NDC with
  :func:`hkpd.camera_conventions.pixels_to_ndc`; only ``visible`` keypoints count.
- 3D targets are the batch's camera-frame ``joints3d``, made pelvis-relative the same way.

Reductions: every term is a mean over the batch (and over samples). The NLLs sum over joints /
coefficients; the 2D terms average the squared Euclidean NDC error over visible keypoints; the
3D term averages the squared Euclidean error (m²) over the 24 joints.
"""

from __future__ import annotations

from dataclasses import replace

import torch

from hkpd.alignment import root_align
from hkpd.body.body_model import BodyModel
from hkpd.body.root_relative import PELVIS, pelvis_relative_body
from hkpd.camera_conventions import pixels_to_ndc, weak_perspective_project
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher, body_shape_distribution
from hkpd.kinematic_tree import BODY_PARENTS
from hkpd.network.output_decoding import full_precision
from hkpd.synthesis.batch import TrainingBatch
from hkpd.training.schedule import LossWeights


def shape_nll(mean: torch.Tensor, std: torch.Tensor, betas: torch.Tensor) -> torch.Tensor:
    """Gaussian shape NLL (paper Eq. 7), summed over coefficients, mean over the batch.

    Args:
        mean, std: ``(B, K)`` predicted shape distribution.
        betas: ``(B, K)`` ground-truth coefficients.

    Returns:
        Scalar.
    """
    return -body_shape_distribution(mean, std).log_prob(betas).mean()


def tpose_vertex_loss(body: BodyModel, mean: torch.Tensor, betas: torch.Tensor) -> torch.Tensor:
    """Per-vertex T-pose shape loss: mean squared distance (m²) between the rest-pose vertices
    of the predicted shape mean and of the true shape (no pose, no global rotation, no camera).

    The rest vertices are linear in the coefficients, so the difference is
    ``shapedirs @ (mean - betas)``: a coefficient that barely moves the body costs little.

    Args:
        body: the body model (its ``shapedirs`` ``(V, 3, K)``).
        mean, betas: ``(B, K)`` predicted mean and true coefficients.

    Returns:
        Scalar: mean over examples and vertices of the squared distance.
    """
    difference = torch.einsum("vck,bk->bvc", body.shapedirs.to(mean.dtype), mean - betas)
    return difference.square().sum(-1).mean()


def pose_nll(F: torch.Tensor | KinematicMatrixFisher, body_pose: torch.Tensor) -> torch.Tensor:
    """Matrix-Fisher NLL of the relative joint rotations (paper Eq. 8).

    ``log c(F_i) - tr(F_i^T R_i)`` summed over the 23 joints, mean over the batch; the normaliser
    is exact and differentiable.

    Args:
        F: ``(B, 23, 3, 3)`` predicted parameters, or the distribution already built from them
            (which reuses its cached SVD).
        body_pose: ``(B, 23, 3, 3)`` ground-truth relative rotations.

    Returns:
        Scalar.
    """
    pose = F if isinstance(F, KinematicMatrixFisher) else KinematicMatrixFisher(F, BODY_PARENTS)
    return -pose.log_prob(body_pose).mean()


def global_rotation_loss(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """``||R_target - R_pred||_F^2``, mean over the batch (``(B, 3, 3)`` each); scalar."""
    return (predicted - target).square().sum(dim=(-1, -2)).mean()


def keypoint_reprojection_loss(
    predicted: torch.Tensor, target: torch.Tensor, visible: torch.Tensor
) -> torch.Tensor:
    """Squared Euclidean 2D error over visible keypoints (paper Eq. 10, averaged).

    Args:
        predicted: ``(B, L, 2)`` or ``(B, S, L, 2)`` (S samples per example) predicted
            keypoints, NDC.
        target: ``(B, L, 2)`` target keypoints, NDC.
        visible: ``(B, L)`` bool (or 0/1) visibility of the targets.

    Returns:
        Scalar: the sum of squared errors over visible keypoints (and samples) divided by
        their number; 0 (still connected to the graph) when nothing is visible.
    """
    if predicted.dim() == 3:
        predicted = predicted.unsqueeze(1)
    if predicted.shape[0] != target.shape[0] or predicted.shape[2:] != target.shape[1:]:
        raise ValueError(
            f"predicted keypoints {tuple(predicted.shape)} do not match targets "
            f"{tuple(target.shape)} (expected (B, L, 2) or (B, S, L, 2))"
        )
    if visible.shape != target.shape[:2]:
        raise ValueError(f"visible must be {tuple(target.shape[:2])}, got {tuple(visible.shape)}")
    mask = visible.to(predicted.dtype).unsqueeze(1)  # (B, 1, L)
    squared = (predicted - target.unsqueeze(1)).square().sum(-1)  # (B, S, L)
    count = mask.sum() * predicted.shape[1]
    return (squared * mask).sum() / count.clamp_min(1.0)


def joints3d_loss(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Mean squared Euclidean error (m²) of pelvis-aligned 3D joints.

    Args:
        predicted, target: ``(B, J, 3)`` joints in the same frame (metres); each is made
            relative to its own joint :data:`PELVIS` first, so translations do not matter.

    Returns:
        Scalar.
    """
    predicted, target = root_align(predicted, PELVIS), root_align(target, PELVIS)
    return (predicted - target).square().sum(-1).mean()


def compute_losses(
    output: BodyDistribution,
    batch: TrainingBatch,
    body: BodyModel,
    weights: LossWeights,
    num_samples: int = 8,
    crop_size: int | None = None,
    generator: torch.Generator | None = None,
    shape_from_nll_only: bool = False,
) -> dict[str, torch.Tensor]:
    """Every loss term with a non-zero weight, and their weighted sum.

    Args:
        output: the network's prediction for ``batch``.
        batch: the targets (``body_pose``, ``global_orient``, ``betas``, ``keypoints2d``,
            ``visible``, ``joints3d`` are used).
        body: body model on the same device and dtype as the prediction.
        weights: the active :class:`LossWeights` (e.g. ``schedule.weights_at(step)``).
        num_samples: K, bodies sampled per example for the 2D samples loss.
        crop_size: the pixel size that ``batch.keypoints2d`` refers to; None (default) reads it
            from ``batch.proxy``, which is always right for batches from the data generator.
        generator: optional random generator for the samples.
        shape_from_nll_only: pose the bodies of the 2D and 3D joint terms with the predicted
            shape distribution *detached*, so that only the shape NLL (and the T-pose vertex
            loss, when on) trains it. Otherwise the
            joint terms (the samples loss above all, weighted 1000-16000) also push the shape,
            and where poses are hard to read they bend it to absorb pose errors (measured on
            rolled views: their gradient on the shape mean is 17-140× the NLL's).

    Returns:
        ``{term: scalar}`` for each active term of :data:`hkpd.training.schedule.LOSS_TERMS`
        (unweighted) plus ``"total"`` (weighted sum), all connected to the graph.

    The losses are computed in full precision with ``torch.autocast`` disabled, so they may be
    called inside a mixed-precision region.
    """
    with torch.autocast(output.F.device.type, enabled=False):
        if crop_size is None:
            crop_size = int(batch.proxy.shape[-1])
        return _compute_losses(
            output, batch, body, weights, num_samples, crop_size, generator, shape_from_nll_only
        )


def _compute_losses(
    output: BodyDistribution,
    batch: TrainingBatch,
    body: BodyModel,
    weights: LossWeights,
    num_samples: int,
    crop_size: int,
    generator: torch.Generator | None,
    shape_from_nll_only: bool,
) -> dict[str, torch.Tensor]:
    if num_samples < 1 and weights.joints2d_samples > 0:
        raise ValueError(f"num_samples must be >= 1 for the samples loss, got {num_samples}")
    if output.batch_size != batch.batch_size:
        raise ValueError(
            f"prediction has batch size {output.batch_size}, targets {batch.batch_size}"
        )
    output = output.map(full_precision)
    terms: dict[str, torch.Tensor] = {}
    pose = output.pose_distribution()
    if weights.shape_nll > 0:
        terms["shape_nll"] = shape_nll(output.shape_mean, output.shape_std, batch.betas)
    if weights.pose_nll > 0:
        terms["pose_nll"] = pose_nll(pose, batch.body_pose)
    if weights.global_rotation > 0:
        terms["global_rotation"] = global_rotation_loss(output.global_orient, batch.global_orient)
    if weights.shape_tpose_vertices > 0:
        terms["shape_tpose_vertices"] = tpose_vertex_loss(body, output.shape_mean, batch.betas)
    if shape_from_nll_only:  # the joint terms below see a shape they cannot move
        output = replace(
            output, shape_mean=output.shape_mean.detach(), shape_std=output.shape_std.detach()
        )

    target_ndc = pixels_to_ndc(batch.keypoints2d.to(output.F.dtype), crop_size)
    if weights.joints2d_mode > 0 or weights.joints3d_mode > 0:
        keypoints, joints = pelvis_relative_body(
            body, output.shape_mean, pose.mode, output.global_orient
        )
        if weights.joints2d_mode > 0:
            projected = weak_perspective_project(keypoints, output.camera)
            terms["joints2d_mode"] = keypoint_reprojection_loss(
                projected, target_ndc, batch.visible
            )
        if weights.joints3d_mode > 0:
            terms["joints3d_mode"] = joints3d_loss(joints, batch.joints3d.to(joints.dtype))
    if weights.joints2d_samples > 0:
        terms["joints2d_samples"] = _samples_reprojection_loss(
            output, pose, body, target_ndc, batch.visible, num_samples, generator
        )
    total = sum(getattr(weights, name) * value for name, value in terms.items())
    terms["total"] = total if isinstance(total, torch.Tensor) else output.F.sum() * 0.0
    return terms


def _samples_reprojection_loss(
    output: BodyDistribution,
    pose: KinematicMatrixFisher,
    body: BodyModel,
    target_ndc: torch.Tensor,
    visible: torch.Tensor,
    num_samples: int,
    generator: torch.Generator | None,
) -> torch.Tensor:
    """2D loss of ``num_samples`` reparameterised pose and shape samples per example."""
    batch = output.batch_size
    poses = pose.rsample(num_samples, generator=generator)  # (S, B, 23, 3, 3)
    betas = output.sample_betas(num_samples, generator)  # reparameterised, (S, B, K)
    orient = output.global_orient.expand(num_samples, batch, 3, 3)
    keypoints, _ = pelvis_relative_body(
        body, betas.flatten(0, 1), poses.flatten(0, 1), orient.flatten(0, 1)
    )
    keypoints = keypoints.unflatten(0, (num_samples, batch)).transpose(0, 1)  # (B, S, 17, 3)
    projected = weak_perspective_project(keypoints, output.camera)
    return keypoint_reprojection_loss(projected, target_ndc, visible)

"""Evaluation metrics of the paper (Section 4 and supplementary Table 4), as pure functions.

All functions take torch tensors and return **per-example** values (batch first), so that
callers can average over a dataset, plot sorted error curves, or take minima over samples.
3D metrics are returned in **metres**; multiply by :data:`MILLIMETRES_PER_METRE` for the
millimetres the paper's tables report. 2D errors are in **pixels** of the crop the keypoints are
given in (256 px in the paper).

Definitions:

- **MPJPE**: mean Euclidean distance between predicted and target 3D joints after subtracting
  each set's root joint (the pelvis), no scaling or rotation.
- **MPJPE-SC** (scale-corrected, STRAPS): the prediction is centred on its centroid, scaled to
  the target's RMS distance from its centroid and moved onto the target's centroid; then mean
  per-joint distance (see :func:`hkpd.alignment.rms_scale_align`). This removes the
  scale/depth ambiguity of a monocular prediction. ``method="least_squares"`` instead uses the
  least-squares scale after root alignment.
- **MPJPE-PA** (Procrustes-aligned): the prediction is mapped by the optimal similarity
  transform (scale, rotation, translation) before the mean per-joint distance.
- **PVE-T-SC**: per-vertex distance between the predicted and target bodies in the T-pose
  (shape only; ``BodyModel.tpose(betas)``), after the STRAPS scale correction.
- **2D joint error**: mean pixel distance over *visible* target keypoints; for several samples
  per example the error is averaged over samples.
- **min-of-N**: for per-sample errors ``(S, B)``, the minimum over the first N samples of each
  example (Biggs et al. 2020; paper supplementary Table 4).
- **sample diversity**: per joint, the mean distance of sampled 3D points from their sample mean
  (the paper's per-vertex uncertainty, applied to joints), averaged separately over visible
  and invisible joints.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from hkpd.alignment import (
    least_squares_scale_align,
    procrustes_align,
    rms_scale_align,
    root_align,
)
from hkpd.body.body_model import BodyModel

MILLIMETRES_PER_METRE = 1000.0
"""Multiply the 3D metrics (metres) by this for the paper's millimetres."""

MIN_OF_N_COUNTS = (1, 5, 10, 25)
"""Sample counts of the paper's min-of-N table."""


def _mean_distance(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return (predicted - target).norm(dim=-1).mean(-1)


def mpjpe(predicted: torch.Tensor, target: torch.Tensor, root_index: int = 0) -> torch.Tensor:
    """Root-aligned mean per-joint position error.

    Args:
        predicted, target: ``(B, J, 3)`` joints, metres (any common frame orientation).
        root_index: joint subtracted from each set (0 = pelvis for SMPL joints).

    Returns:
        ``(B,)`` metres.
    """
    return _mean_distance(root_align(predicted, root_index), root_align(target, root_index))


def mpjpe_scale_corrected(
    predicted: torch.Tensor, target: torch.Tensor, method: str = "rms", root_index: int = 0
) -> torch.Tensor:
    """MPJPE-SC: mean per-joint error after scale correction.

    Args:
        predicted, target: ``(B, J, 3)`` joints, metres.
        method: ``"rms"`` (STRAPS, the paper's protocol) or ``"least_squares"`` (least-squares
            scale after aligning ``root_index``).
        root_index: used by ``"least_squares"`` only.

    Returns:
        ``(B,)`` metres.
    """
    if method == "rms":
        aligned = rms_scale_align(predicted, target)
    elif method == "least_squares":
        aligned = least_squares_scale_align(predicted, target, root_index)
    else:
        raise ValueError(f"method must be 'rms' or 'least_squares', got {method!r}")
    return _mean_distance(aligned, target)


def mpjpe_procrustes(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """MPJPE-PA: mean per-joint error after the optimal similarity transform; ``(B,)`` metres."""
    return _mean_distance(procrustes_align(predicted, target), target)


def pve_t_sc(predicted_vertices: torch.Tensor, target_vertices: torch.Tensor) -> torch.Tensor:
    """PVE-T-SC from T-pose vertices ``(B, V, 3)`` (metres); ``(B,)`` metres."""
    return _mean_distance(rms_scale_align(predicted_vertices, target_vertices), target_vertices)


def pve_t_sc_from_betas(
    body: BodyModel, predicted_betas: torch.Tensor, target_betas: torch.Tensor
) -> torch.Tensor:
    """PVE-T-SC of shape coefficients ``(B, K)`` each, via ``body.tpose``; ``(B,)`` metres."""
    return pve_t_sc(body.tpose(predicted_betas), body.tpose(target_betas))


def joint_error_2d(
    predicted: torch.Tensor, target: torch.Tensor, visible: torch.Tensor
) -> torch.Tensor:
    """Mean 2D keypoint distance over visible keypoints (and over samples).

    Args:
        predicted: ``(B, L, 2)`` keypoints (e.g. of the mode body) or ``(S, B, L, 2)`` for S
            samples per example, pixels.
        target: ``(B, L, 2)`` pixels.
        visible: ``(B, L)`` bool.

    Returns:
        ``(B,)`` pixels; NaN for examples without visible keypoints (use ``nanmean``).
    """
    if predicted.dim() == 3:
        predicted = predicted.unsqueeze(0)
    if predicted.shape[1:] != target.shape or visible.shape != target.shape[:2]:
        raise ValueError(
            f"expected predicted (B, L, 2) or (S, B, L, 2), target (B, L, 2), visible (B, L); "
            f"got {tuple(predicted.shape)}, {tuple(target.shape)}, {tuple(visible.shape)}"
        )
    mask = visible.to(predicted.dtype)
    distance = (predicted - target).norm(dim=-1).mean(0)  # (B, L), mean over samples
    count = mask.sum(-1)
    total = (distance * mask).sum(-1)
    return torch.where(count > 0, total / count.clamp_min(1.0), torch.full_like(total, torch.nan))


def min_of_n(
    sample_errors: torch.Tensor, counts: Sequence[int] = MIN_OF_N_COUNTS
) -> dict[int, torch.Tensor]:
    """Minimum error over the first N samples of each example, for each N in ``counts``.

    Args:
        sample_errors: ``(S, B)`` per-sample errors (e.g. MPJPE of each sampled body).
        counts: the N values; each must be between 1 and S.

    Returns:
        ``{N: (B,)}``.
    """
    if sample_errors.dim() != 2:
        raise ValueError(f"sample_errors must be (S, B), got {tuple(sample_errors.shape)}")
    available = sample_errors.shape[0]
    result = {}
    for n in counts:
        if not 1 <= n <= available:
            raise ValueError(f"min-of-{n} needs at least {n} samples, got {available}")
        result[int(n)] = sample_errors[:n].amin(0)
    return result


def per_joint_spread(samples: torch.Tensor) -> torch.Tensor:
    """Mean distance of samples from their mean, per point.

    Args:
        samples: ``(S, B, L, 3)`` sampled points (e.g. root-relative 3D joints), metres.

    Returns:
        ``(B, L)`` metres (0 when all samples coincide).
    """
    if samples.dim() != 4 or samples.shape[-1] != 3:
        raise ValueError(f"samples must be (S, B, L, 3), got {tuple(samples.shape)}")
    return (samples - samples.mean(0, keepdim=True)).norm(dim=-1).mean(0)


def sample_diversity(samples: torch.Tensor, visible: torch.Tensor) -> dict[str, torch.Tensor]:
    """Per-example sample spread of visible and of invisible joints.

    Args:
        samples: ``(S, B, L, 3)`` sampled points, metres.
        visible: ``(B, L)`` bool visibility of each point in the image.

    Returns:
        ``{"visible": (B,), "invisible": (B,)}`` mean :func:`per_joint_spread` over the
        example's visible / invisible joints, metres; NaN where an example has none.
    """
    spread = per_joint_spread(samples)
    if visible.shape != spread.shape:
        raise ValueError(f"visible must be {tuple(spread.shape)}, got {tuple(visible.shape)}")
    result = {}
    for name, mask in (("visible", visible), ("invisible", ~visible.bool())):
        weights = mask.to(spread.dtype)
        count = weights.sum(-1)
        total = (spread * weights).sum(-1)
        result[name] = torch.where(
            count > 0, total / count.clamp_min(1.0), torch.full_like(total, torch.nan)
        )
    return result

"""Rigid, scale and similarity alignments of predicted point sets to targets (batched torch).

Shared by the training losses and the evaluation metrics, so it sits below both.

All functions take ``(B, N, 3)`` predicted and target points (joints or vertices, metres) and
return the predicted points moved onto the target's frame; they are differentiable.
"""

from __future__ import annotations

import torch

_EPS = 1e-12


def _check_pair(predicted: torch.Tensor, target: torch.Tensor) -> None:
    if predicted.shape != target.shape or predicted.dim() != 3 or predicted.shape[-1] != 3:
        raise ValueError(
            "predicted and target must both have shape (B, N, 3), got "
            f"{tuple(predicted.shape)} and {tuple(target.shape)}"
        )


def root_align(points: torch.Tensor, root_index: int = 0) -> torch.Tensor:
    """``(B, N, 3)`` points minus their point ``root_index`` (e.g. the pelvis joint)."""
    return points - points[:, root_index : root_index + 1]


def rms_scale_align(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """STRAPS scale correction: match the target's centroid and RMS distance from it.

    The prediction is centred on its centroid, scaled so that its root-mean-square distance
    from the centroid equals the target's, and moved to the target's centroid. This is the
    "scale-corrected" (-SC) protocol of STRAPS (Sengupta et al. 2020), which the paper uses for
    MPJPE-SC and PVE-T-SC. No rotation.
    """
    _check_pair(predicted, target)
    p_centre = predicted.mean(1, keepdim=True)
    t_centre = target.mean(1, keepdim=True)
    p = predicted - p_centre
    t = target - t_centre
    p_rms = p.square().sum((1, 2), keepdim=True).div(p.shape[1]).sqrt()
    t_rms = t.square().sum((1, 2), keepdim=True).div(t.shape[1]).sqrt()
    return p * (t_rms / p_rms.clamp_min(_EPS)) + t_centre


def least_squares_scale_align(
    predicted: torch.Tensor, target: torch.Tensor, root_index: int = 0
) -> torch.Tensor:
    """Root-align both, then scale the prediction by ``argmin_s ||s p - t||²``.

    ``s = <p, t> / <p, p>`` over all root-relative coordinates; the result is expressed
    relative to the target's root point. No rotation.
    """
    _check_pair(predicted, target)
    p = root_align(predicted, root_index)
    t = root_align(target, root_index)
    scale = (p * t).sum((1, 2), keepdim=True) / p.square().sum((1, 2), keepdim=True).clamp_min(_EPS)
    return scale * p + target[:, root_index : root_index + 1]


def procrustes_align(predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Optimal similarity transform (scale, rotation, translation) of the prediction.

    Solves ``min_{s, R ∈ SO(3), t} Σ_i ||s R p_i + t - q_i||²`` in closed form (Umeyama 1991):
    with centred points and ``P^T Q = U Σ V^T``, ``R = V D U^T`` where
    ``D = diag(1, 1, det(V U^T))`` excludes reflections, and ``s = tr(Σ D) / ||P||²``.
    """
    _check_pair(predicted, target)
    p_centre = predicted.mean(1, keepdim=True)
    t_centre = target.mean(1, keepdim=True)
    p = predicted - p_centre
    t = target - t_centre
    covariance = p.transpose(1, 2) @ t  # (B, 3, 3)
    U, S, Vh = torch.linalg.svd(covariance)
    V = Vh.transpose(1, 2)
    sign = torch.sign(torch.linalg.det(V @ U.transpose(1, 2)))
    sign = torch.where(sign == 0, torch.ones_like(sign), sign)
    D = torch.ones_like(S)
    D[:, 2] = sign
    rotation = V @ torch.diag_embed(D) @ U.transpose(1, 2)
    scale = (S * D).sum(1) / p.square().sum((1, 2)).clamp_min(_EPS)
    return scale[:, None, None] * (p @ rotation.transpose(1, 2)) + t_centre

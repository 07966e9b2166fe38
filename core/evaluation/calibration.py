"""Are the predicted pose distributions honest? Coverage of the true joint rotations.

A distribution is *calibrated* when its stated uncertainty matches its errors: the true
rotation should fall inside the distribution's 50% most probable region half the time, inside
its 90% region nine times in ten. For a matrix-Fisher distribution the density is
``exp(tr(F^T R))`` up to a constant, so whether a rotation lies inside the region that holds a
share ``q`` of the probability is read off by ranking: the *truth's rank* is the share of
samples more probable than the truth, and the truth is inside the ``q`` region when its rank is
below ``q``. A calibrated model's ranks are uniform on [0, 1]; an over-confident one's pile up
near 1 (the truth is less probable than most samples), an under-confident one's near 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from hkpd.distributions import MatrixFisher

COVERAGE_LEVELS: tuple[float, ...] = (0.5, 0.9)
"""The probability shares of the regions that :func:`rotation_coverage` checks."""


def _log_density_up_to_constant(F: torch.Tensor, rotations: torch.Tensor) -> torch.Tensor:
    """``log p(R)`` (``tr(F^T R)`` up to a per-distribution constant), float64 and free of
    cancellation (:meth:`MatrixFisher.log_prob`): in float32 ``tr(F^T R)`` cannot rank
    rotations at concentrations of 1e7 and more. ``F`` ``(..., 3, 3)`` and ``rotations``
    broadcastable to it; returns ``(...)``."""
    with torch.no_grad():
        return MatrixFisher(F, validate_args=False).log_prob_exact(rotations)


def truth_rank(F: torch.Tensor, samples: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Share of samples that are more probable than the true rotation, per joint.

    Args:
        F: ``(B, J, 3, 3)`` matrix-Fisher parameters (one distribution per example and joint;
            the kinematic model's joints are conditionally independent given ``F``).
        samples: ``(S, B, J, 3, 3)`` rotations drawn from those distributions.
        truth: ``(B, J, 3, 3)`` the true rotations.

    Returns:
        ``(B, J)`` ranks in [0, 1], resolution ``1 / S``.
    """
    if samples.shape[1:] != F.shape or truth.shape != F.shape:
        raise ValueError(
            f"expected F (B, J, 3, 3), samples (S, B, J, 3, 3) and truth like F, got "
            f"{tuple(F.shape)}, {tuple(samples.shape)} and {tuple(truth.shape)}"
        )
    truth_score = _log_density_up_to_constant(F, truth)
    sample_score = _log_density_up_to_constant(F.unsqueeze(0), samples)
    return (sample_score > truth_score.unsqueeze(0)).to(F.dtype).mean(0)


def rotation_coverage(
    F: torch.Tensor,
    samples: torch.Tensor,
    truth: torch.Tensor,
    levels: Sequence[float] = COVERAGE_LEVELS,
) -> dict[float, torch.Tensor]:
    """Per example, the share of joints whose true rotation lies in each highest-density region.

    Args:
        F, samples, truth: as in :func:`truth_rank`.
        levels: probability shares ``q`` of the regions (e.g. 0.9 for the 90% region).

    Returns:
        ``{q: (B,)}`` shares in [0, 1]; a calibrated model averages ``q`` over many examples.
    """
    ranks = truth_rank(F, samples, truth)
    return {level: (ranks < level).to(F.dtype).mean(-1) for level in levels}


def point_truth_rank(
    mode: torch.Tensor, samples: torch.Tensor, truth: torch.Tensor
) -> torch.Tensor:
    """Share of samples closer to the mode than the true point, per point (2D keypoints).

    The regions are discs about the mode, so the rank needs no density: a point drawn from the
    predicted distribution is as likely to be the k-th nearest to the mode as any sample, and a
    calibrated prediction's ranks are uniform, as for :func:`truth_rank`. Used on real photos,
    where the truth is an annotated keypoint and only the body's projection is predicted.

    Args:
        mode: ``(..., P, 2)`` the most likely body's projected points (pixels).
        samples: ``(S, ..., P, 2)`` the sampled bodies' projected points.
        truth: ``(..., P, 2)`` the true points.

    Returns:
        ``(..., P)`` ranks in [0, 1], resolution ``1 / S``.
    """
    if samples.shape[1:] != mode.shape or truth.shape != mode.shape or mode.shape[-1] != 2:
        raise ValueError(
            f"expected mode (..., P, 2), samples (S, ..., P, 2) and truth like mode, got "
            f"{tuple(mode.shape)}, {tuple(samples.shape)} and {tuple(truth.shape)}"
        )
    truth_distance = (truth - mode).norm(dim=-1)
    sample_distance = (samples - mode.unsqueeze(0)).norm(dim=-1)
    return (sample_distance < truth_distance.unsqueeze(0)).to(mode.dtype).mean(0)


def calibrated_coverage(level: float, num_samples: int) -> float:
    """The coverage a calibrated prediction averages when ranks have ``num_samples`` samples:
    the truth is inside the ``level`` region when fewer than ``level × S`` samples beat it, which
    happens with probability ``(⌈level × S⌉) / (S + 1)`` (25 samples: 0.5 and 0.885)."""
    if num_samples < 1 or not 0.0 < level < 1.0:
        raise ValueError(f"need num_samples >= 1 and 0 < level < 1, got {num_samples}, {level}")
    return math.ceil(level * num_samples - 1e-9) / (num_samples + 1)

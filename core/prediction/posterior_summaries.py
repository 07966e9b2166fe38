"""Summaries of a body posterior for research scripts: the uncertainty per body part and the
posterior's log density of given bodies.

Pure functions of tensors and a :class:`~hkpd.distributions.BodyDistribution`, so that
:class:`~hkpd.prediction.posterior.BodyPosterior` can offer them as methods
(``part_uncertainty(num_samples)``, ``log_prob(body_pose, betas)``) and scripts can call them on
any record.

Units of :func:`posterior_log_prob`: the log (nats) of a density with respect to the product of
the Haar probability measure on each of the 23 joints' SO(3) (each normalised to total mass 1,
so the uniform distribution over a joint's rotations has density 1, log density 0) and the
Lebesgue measure on the 10 (dimensionless) shape coefficients β. The pose part is the
hierarchical matrix-Fisher distribution's: given the per-joint parameters ``F`` (which the
network computes down the kinematic tree), the relative rotations are independent, so it is the
sum of the 23 joints' matrix-Fisher log densities
(:meth:`hkpd.distributions.KinematicMatrixFisher.log_prob`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from hkpd.distributions import BodyDistribution

ROTATION_TOLERANCE = 1e-3
"""Largest ``|R^T R - I|`` entry (and ``|det R - 1|``) of a pose accepted by
:func:`posterior_log_prob`: float32 rotations composed a few times stay within ~1e-6."""


def part_uncertainty(
    vertex_uncertainty: torch.Tensor,
    part_labels: torch.Tensor,
    part_names: Sequence[str],
) -> dict[str, float]:
    """The mean per-vertex uncertainty of each body part.

    Args:
        vertex_uncertainty: ``(V,)`` per-vertex uncertainty, metres (e.g.
            ``BodyPosterior.vertex_uncertainty(n)``: mean distance of sampled vertices from
            their mean).
        part_labels: ``(V,)`` integer body part of each vertex, an index into ``part_names``
            (``BodyModel.part_labels``).
        part_names: the parts' names (``BodyModel.part_names``, 24 for the body model).

    Returns:
        ``{part name: mean uncertainty of its vertices, metres}`` for every name in
        ``part_names``, in order; NaN for a part no vertex belongs to.

    Raises:
        ValueError: not 1-D, different lengths, labels that are not integers or not indices
            into ``part_names``, or repeated part names.
    """
    values = torch.as_tensor(vertex_uncertainty)
    labels = torch.as_tensor(part_labels)
    names = tuple(part_names)
    if values.ndim != 1 or labels.ndim != 1 or values.shape != labels.shape:
        raise ValueError(
            "part_uncertainty needs vertex_uncertainty (V,) and part_labels (V,), got "
            f"{tuple(values.shape)} and {tuple(labels.shape)}"
        )
    if labels.is_floating_point() or labels.is_complex() or labels.dtype == torch.bool:
        raise ValueError(f"part_labels must be integer part indices, got {labels.dtype}")
    if len(set(names)) != len(names):
        raise ValueError(f"part_names must be distinct, got {names}")
    if labels.numel() and (int(labels.min()) < 0 or int(labels.max()) >= len(names)):
        raise ValueError(
            f"part_labels must index the {len(names)} part_names (0 to {len(names) - 1}), "
            f"got labels from {int(labels.min())} to {int(labels.max())}"
        )
    labels = labels.to(device=values.device, dtype=torch.long)
    sums = torch.zeros(len(names), dtype=torch.float64, device=values.device)
    sums.index_add_(0, labels, values.detach().to(torch.float64))
    counts = torch.bincount(labels, minlength=len(names)).to(torch.float64)
    means = torch.where(counts > 0, sums / counts.clamp_min(1.0), math.nan)
    return {name: float(mean) for name, mean in zip(names, means.tolist(), strict=True)}


def posterior_log_prob(
    distribution: BodyDistribution, body_pose: torch.Tensor, betas: torch.Tensor
) -> torch.Tensor:
    """Log density of N bodies under one person's distribution: the hierarchical matrix-Fisher
    density of the 23 relative joint rotations plus the shape Gaussian's density of β.

    Args:
        distribution: one person's distribution (batch shape ``()``), e.g.
            ``BodyPosterior.distribution``. Its shape part is the diagonal Gaussian
            ``N(shape_mean, shape_std²)``; a posterior with sex as a latent adds its mixture
            elsewhere. The global rotation and the camera are point estimates and take no part.
        body_pose: ``(N, 23, 3, 3)`` relative joint rotations (parents before children,
            :data:`hkpd.kinematic_tree.BODY_PARENTS`).
        betas: ``(N, K)`` shape coefficients (K = 10).

    Returns:
        ``(N,)`` float64 ``log p(pose) + log p(β)``, nats; the units are in the module's
        docstring (Haar probability measure on SO(3)^23, Lebesgue measure on β). Computed in
        float64; gradients reach ``distribution``'s tensors, the poses and the betas.

    Raises:
        ValueError: a batched distribution, shapes that do not fit it, different N, non-finite
            values, or poses that are not rotation matrices (within :data:`ROTATION_TOLERANCE`).
    """
    _check_log_prob_inputs(distribution, body_pose, betas)
    exact = distribution.to(torch.float64)
    pose = exact.pose_distribution().log_prob(body_pose.to(torch.float64))
    shape = exact.shape_distribution().log_prob(betas.to(torch.float64))
    return pose + shape


def _check_log_prob_inputs(
    distribution: BodyDistribution, body_pose: torch.Tensor, betas: torch.Tensor
) -> None:
    """The ValueErrors of :func:`posterior_log_prob`."""
    joints = tuple(distribution.F.shape[-3:])
    coefficients = tuple(distribution.shape_mean.shape)
    if distribution.F.ndim != 3 or len(coefficients) != 1:
        raise ValueError(
            "posterior_log_prob needs one person's distribution (batch shape ()), got F "
            f"{tuple(distribution.F.shape)}; take one with distribution.rows(i)"
        )
    if body_pose.ndim != 4 or tuple(body_pose.shape[1:]) != joints:
        raise ValueError(f"body_pose must be (N, *{joints}), got {tuple(body_pose.shape)}")
    if betas.ndim != 2 or tuple(betas.shape[1:]) != coefficients:
        raise ValueError(f"betas must be (N, *{coefficients}), got {tuple(betas.shape)}")
    if body_pose.shape[0] != betas.shape[0]:
        raise ValueError(
            f"body_pose and betas must hold the same N bodies, got {body_pose.shape[0]} and "
            f"{betas.shape[0]}"
        )
    if not (torch.isfinite(body_pose).all() and torch.isfinite(betas).all()):
        raise ValueError("body_pose and betas must be finite")
    rotations = body_pose.detach().to(torch.float64)
    identity = torch.eye(3, dtype=torch.float64, device=rotations.device)
    orthogonal = (rotations.transpose(-1, -2) @ rotations - identity).abs().amax(dim=(-1, -2))
    handed = (torch.linalg.det(rotations) - 1.0).abs()
    worst = float(torch.maximum(orthogonal, handed).amax()) if rotations.numel() else 0.0
    if worst > ROTATION_TOLERANCE:
        raise ValueError(
            f"body_pose must be rotation matrices (R^T R = I, det R = 1); the worst is off by "
            f"{worst:.3g} (tolerance {ROTATION_TOLERANCE:g}): project them onto SO(3) first"
        )

"""From a Gaussian (Laplace) approximation back to the matrix-Fisher family.

Near its mode ``R̂ = U V^T`` a matrix-Fisher density ``exp tr(F^T R)`` with ``F = U S V^T``,
written in right-perturbation coordinates ``R = R̂ Exp(δ)``, is

    tr(F^T R) = tr(S) - ½ δ^T H δ + O(|δ|^3),    H = tr(M) I - M,    M = F^T R̂ = V S V^T,

(the linear term vanishes because ``M`` is symmetric). Conversely a symmetric positive
semi-definite precision ``H`` at a rotation ``R̂`` is matched exactly by

    M = ½ tr(H) I - H,    F = R̂ M,

whose proper singular values ``(h2 + h3 - h1, h1 + h3 - h2, h1 + h2 - h3) / 2`` always satisfy
``s1 >= s2 >= |s3|`` for eigenvalues ``h1 <= h2 <= h3 >= 0``: every such Gaussian has a
matrix-Fisher twin with the same mode and the same curvature there.

A product of independent per-joint distributions can only carry a block-diagonal precision.
Taking the diagonal blocks of the joint precision would count evidence shared along a chain once
per joint (a wrist keypoint constrains shoulder *and* elbow, but not both at full strength), so
:func:`marginal_precisions` inverts the joint precision, keeps each joint's marginal covariance
and inverts that: each joint then has the right marginal spread.
"""

from __future__ import annotations

import torch


def matrix_fisher_from_precision(mode: torch.Tensor, precision: torch.Tensor) -> torch.Tensor:
    """The matrix-Fisher parameter with mode ``mode`` and curvature ``precision`` there.

    Args:
        mode: ``(..., 3, 3)`` rotation matrices.
        precision: ``(..., 3, 3)`` symmetric positive semi-definite, in right-perturbation
            coordinates (``R = mode @ Exp(δ)``), units 1/rad².

    Returns:
        ``(..., 3, 3)`` ``F = mode (½ tr(H) I - H)``.
    """
    symmetric = 0.5 * (precision + precision.transpose(-1, -2))
    trace = symmetric.diagonal(dim1=-2, dim2=-1).sum(-1)
    eye = torch.eye(3, dtype=precision.dtype, device=precision.device)
    M = 0.5 * trace[..., None, None] * eye - symmetric
    return mode @ M


def matrix_fisher_precision(F: torch.Tensor, at: torch.Tensor) -> torch.Tensor:
    """Curvature ``tr(M) I - M`` (``M = sym(F^T at)``) of ``-tr(F^T R)`` at rotation ``at``.

    At the distribution's mode this is its Laplace precision; elsewhere it is the exact Hessian
    in right-perturbation coordinates minus the skew part, and may be indefinite far from the
    mode.

    Args:
        F: ``(..., 3, 3)``.
        at: ``(..., 3, 3)`` rotations.

    Returns:
        ``(..., 3, 3)`` symmetric.
    """
    product = F.transpose(-1, -2) @ at
    M = 0.5 * (product + product.transpose(-1, -2))
    trace = M.diagonal(dim1=-2, dim2=-1).sum(-1)
    eye = torch.eye(3, dtype=F.dtype, device=F.device)
    return trace[..., None, None] * eye - M


def marginal_precisions(precision: torch.Tensor, blocks: int, block_size: int = 3) -> torch.Tensor:
    """Per-block marginal precisions of a Gaussian with joint precision ``precision``.

    Args:
        precision: ``(..., N, N)`` symmetric positive definite; its first ``blocks ×
            block_size`` variables form the blocks (any further ones are marginalised out too).
        blocks: number of consecutive blocks.
        block_size: variables per block.

    Returns:
        ``(..., blocks, block_size, block_size)``: ``inv(Σ_bb)`` with ``Σ = inv(precision)``.
    """
    covariance = torch.linalg.inv(precision)
    spans = [slice(i * block_size, (i + 1) * block_size) for i in range(blocks)]
    diagonal_blocks = torch.stack([covariance[..., span, span] for span in spans], dim=-3)
    diagonal_blocks = 0.5 * (diagonal_blocks + diagonal_blocks.transpose(-1, -2))
    return torch.linalg.inv(diagonal_blocks)

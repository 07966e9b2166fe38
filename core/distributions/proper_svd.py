"""Proper singular value decomposition of 3x3 matrices, with gradients that stay finite.

A *proper* SVD (Lee 2018, used as Eq. 2 of the paper) writes ``F = U diag(S) V^T`` with
``U, V`` in SO(3): the sign that an ordinary SVD puts into ``det(U') det(V')`` is moved onto
the smallest singular value, so ``s1 >= s2 >= |s3|`` and ``s3`` may be negative.

The backward pass uses the usual SVD adjoint, whose ``1 / (s_j^2 - s_i^2)`` terms blow up when
singular values (nearly) coincide, e.g. for ``F = 0`` or an isotropic ``F``. There the
decomposition is not unique; we damp those terms (``x / (x^2 + eps)``) so gradients stay finite.
Where singular values are distinct the gradient is the exact one.
"""

from __future__ import annotations

import torch

# Relative damping of the squared singular-value gaps: gaps below ~sqrt(value) * (1 + s1^2) are
# treated as ties.
_DAMPING = {torch.float64: 1e-20, torch.float32: 1e-12}


class _ProperSVD(torch.autograd.Function):
    @staticmethod
    def forward(F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:  # type: ignore[override]
        U, S, Vh = torch.linalg.svd(F)
        V = Vh.transpose(-1, -2)
        # Flip the last column of U (and V) where its determinant is -1; the product of the two
        # flips goes onto s3, so that F = U diag(S) V^T still holds.
        det_u = torch.linalg.det(U)
        det_v = torch.linalg.det(V)
        flip_u = torch.ones_like(S)
        flip_v = torch.ones_like(S)
        flip_u[..., 2] = torch.sign(det_u)
        flip_v[..., 2] = torch.sign(det_v)
        U = U * flip_u.unsqueeze(-2)
        V = V * flip_v.unsqueeze(-2)
        S = S * flip_u * flip_v
        return U, S, V

    @staticmethod
    def setup_context(ctx, inputs, output) -> None:  # type: ignore[override]
        U, S, V = output
        ctx.save_for_backward(U, S, V)

    @staticmethod
    def backward(ctx, grad_U, grad_S, grad_V):  # type: ignore[override]
        U, S, V = ctx.saved_tensors
        # Gradient with respect to P = U^T dF V (see module docstring):
        #   gP_ii = gS_i
        #   gP_ij = [s_j (Ubar_ij - Ubar_ji) + s_i (Vbar_ij - Vbar_ji)] / (s_j^2 - s_i^2),  i != j
        # with Ubar = U^T gU and Vbar = V^T gV.
        grad_P = torch.zeros_like(U)
        if grad_U is not None or grad_V is not None:
            s_i = S.unsqueeze(-1)
            s_j = S.unsqueeze(-2)
            numerator = torch.zeros_like(U)
            if grad_U is not None:
                u_bar = U.transpose(-1, -2) @ grad_U
                numerator = numerator + s_j * (u_bar - u_bar.transpose(-1, -2))
            if grad_V is not None:
                v_bar = V.transpose(-1, -2) @ grad_V
                numerator = numerator + s_i * (v_bar - v_bar.transpose(-1, -2))
            gap = s_j * s_j - s_i * s_i
            scale = 1.0 + (S * S).amax(-1)[..., None, None]
            damping = _DAMPING.get(S.dtype, 1e-6) * scale * scale
            grad_P = numerator * gap / (gap * gap + damping)
            grad_P = grad_P - torch.diag_embed(torch.diagonal(grad_P, dim1=-2, dim2=-1))
        if grad_S is not None:
            grad_P = grad_P + torch.diag_embed(grad_S)
        return U @ grad_P @ V.transpose(-1, -2)


def proper_svd(F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Proper SVD of a batch of 3x3 matrices.

    Args:
        F: ``(..., 3, 3)`` real matrices.

    Returns:
        ``U (..., 3, 3)``, ``S (..., 3)``, ``V (..., 3, 3)`` with ``U, V`` rotation matrices
        (det +1), ``S = (s1, s2, s3)`` sorted so that ``s1 >= s2 >= |s3|`` (``s3`` may be
        negative), and ``F = U @ diag(S) @ V^T``.
    """
    if F.shape[-2:] != (3, 3):
        raise ValueError(f"proper_svd expects (..., 3, 3) matrices, got shape {tuple(F.shape)}")
    return _ProperSVD.apply(F)

"""Proper SVD: factor properties and finite, correct gradients."""

from __future__ import annotations

import torch

from hkpd.distributions import proper_svd


def test_factors_are_rotations_and_reconstruct_F() -> None:
    torch.manual_seed(0)
    F = torch.randn(500, 3, 3, dtype=torch.float64)
    U, S, V = proper_svd(F)
    eye = torch.eye(3, dtype=torch.float64)
    assert torch.allclose(U.transpose(-1, -2) @ U, eye.expand_as(U), atol=1e-12)
    assert torch.allclose(torch.linalg.det(U), torch.ones(500, dtype=torch.float64))
    assert torch.allclose(torch.linalg.det(V), torch.ones(500, dtype=torch.float64))
    assert torch.allclose(U @ torch.diag_embed(S) @ V.transpose(-1, -2), F, atol=1e-12)
    assert (S[:, 0] >= S[:, 1]).all() and (S[:, 1] >= S[:, 2].abs()).all()
    # The sign of s3 carries the sign of det F.
    assert torch.equal(torch.sign(S[:, 2]), torch.sign(torch.linalg.det(F)))


def test_gauge_invariant_functions_pass_gradcheck() -> None:
    torch.manual_seed(1)
    F = torch.randn(4, 3, 3, dtype=torch.float64, requires_grad=True)
    weights = torch.randn(3, 3, 3, dtype=torch.float64)

    def invariant(f: torch.Tensor) -> torch.Tensor:
        U, S, V = proper_svd(f)
        mode = U @ V.transpose(-1, -2)
        left_gram = U @ torch.diag_embed(S * S) @ U.transpose(-1, -2)
        return (
            (mode * weights[0]).sum() + (left_gram * weights[1]).sum() + (S * weights[2, 0]).sum()
        )

    assert torch.autograd.gradcheck(invariant, (F,))


def test_gradients_stay_finite_at_repeated_singular_values() -> None:
    for F in (
        torch.zeros(3, 3),
        torch.eye(3),
        torch.diag(torch.tensor([5.0, 0.0, 0.0])),
        torch.diag(torch.tensor([3.0, 3.0, -3.0])),
    ):
        F = F.clone().requires_grad_()
        U, S, V = proper_svd(F)
        (U.sum() + S.sum() + V.sum()).backward()
        assert torch.isfinite(F.grad).all()

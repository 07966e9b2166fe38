"""The matrix-Fisher normalising constant ``c(F)`` and its gradient.

With the Haar *probability* measure on SO(3) (so ``c(0) = 1``),

    c(F) = E_R[exp(tr(F^T R))],

which depends only on the proper singular values ``S = (s1, s2, s3)`` of ``F``. Writing a
rotation as a unit quaternion turns ``c`` into a Bingham normaliser on the 3-sphere; pairing
the quaternion's coordinates and integrating out the two circle angles leaves one dimension:

    c(S) = exp(s1 + s2 + s3) * J(S),
    J(S) = int_0^1 I0e(p (1 - t)) exp(-2 q t) I0e(r t) dt,
    p = s1 + s2,  q = s2 + s3,  r = s1 - s2,

where ``I0e(x) = exp(-x) I0(x)``. For a proper SVD ``p, q, r >= 0``, so every factor lies in
(0, 1]: nothing overflows, even at ``s = 1e5``. The integrand has boundary layers of width
``1/q``, ``1/r`` at ``t = 0`` and ``1/p`` at ``t = 1``; tanh-sinh (double-exponential)
quadrature resolves layers of any width, so one fixed set of 117 nodes is accurate to ~1e-9
relative for all ``0 <= s <= 1e5`` (gradients to ~1e-8 absolute) and batches vectorise without
branching.

For very large concentrations about all three axes (beyond 1e5; the shipped model's hands reach
~1e8) the boundary layers become thinner than the nodes resolve, and the density is Gaussian
near its mode to within O(1/κ): there ``J = (8π κ1 κ2 κ3)^(-1/2)`` with ``κ = (s2+s3, s1+s3,
s1+s2)`` is used instead (error < 1e-5 nats).

For tiny ``S`` the quadrature cannot resolve ``log c ~ |S|^2 / 6`` against its own round-off, so
``max|s| < 1e-2`` uses the Taylor series of ``log c`` (through fifth order; the first neglected
term is ~1e-3 |S|^6).

The gradient ``d log c / d s_i = E[Q_ii]`` (``Q = U^T R V``) comes from the same nodes by
differentiating the integrand, using ``d I0e(x)/dx = I1e(x) - I0e(x)``. All arithmetic is done
in float64 and cast back to the input dtype.
"""

from __future__ import annotations

import functools
import math

import torch

_TANH_SINH_HALF_COUNT = 60
_TANH_SINH_STEP = 0.07
_MIN_WEIGHT = 1e-40  # nodes below this weight change log c by < 1e-30 relative
_SERIES_LIMIT = 1e-2
_ASYMPTOTIC_FROM = 1e5
"""Beyond this concentration about every axis the quadrature's boundary layers get too thin
(at 1e7 it lost 1.8e-3 nats, at 1e12 6e-2), and the Gaussian limit is exact to < 1e-5."""


@functools.lru_cache(maxsize=8)
def _tanh_sinh_nodes(device: torch.device) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Tanh-sinh nodes on (0, 1): ``t``, ``1 - t`` (both computed without cancellation), weights.

    Returns three float64 tensors of shape ``(N,)``.
    """
    k = torch.arange(-_TANH_SINH_HALF_COUNT, _TANH_SINH_HALF_COUNT + 1, dtype=torch.float64)
    x = k * _TANH_SINH_STEP
    u = 0.5 * math.pi * torch.sinh(x)
    t = torch.sigmoid(2.0 * u)
    t_complement = torch.sigmoid(-2.0 * u)
    weights = _TANH_SINH_STEP * 0.25 * math.pi * torch.cosh(x) / torch.cosh(u) ** 2
    keep = weights > _MIN_WEIGHT
    return t[keep].to(device), t_complement[keep].to(device), weights[keep].to(device)


def _log_c_series(S: torch.Tensor) -> torch.Tensor:
    """Taylor series of log c for small ``S`` (..., 3), float64; error ~1e-3 |S|^6."""
    s1, s2, s3 = S.unbind(-1)
    sq1, sq2, sq3 = s1 * s1, s2 * s2, s3 * s3
    sum_sq = sq1 + sq2 + sq3
    triple = s1 * s2 * s3
    quartic = sq1 * sq1 + sq2 * sq2 + sq3 * sq3 - sq1 * sq2 - sq1 * sq3 - sq2 * sq3
    return sum_sq / 6.0 + triple / 6.0 - quartic / 180.0 - triple * sum_sq / 90.0


def _quadrature_terms(S64: torch.Tensor) -> dict[str, torch.Tensor]:
    """Integrand pieces of J at the tanh-sinh nodes for float64 ``S64 (..., 3)``."""
    s1, s2, s3 = S64.unbind(-1)
    # Clamps guard against round-off making a proper-SVD quantity slightly negative.
    p = (s1 + s2).clamp_min(0.0).unsqueeze(-1)
    q = (s2 + s3).clamp_min(0.0).unsqueeze(-1)
    r = (s1 - s2).clamp_min(0.0).unsqueeze(-1)
    t, tc, w = _tanh_sinh_nodes(S64.device)
    i0e_p = torch.special.i0e(p * tc)
    i0e_r = torch.special.i0e(r * t)
    weighted = w * i0e_p * torch.exp(-2.0 * q * t) * i0e_r
    return {"p": p, "r": r, "t": t, "tc": tc, "i0e_p": i0e_p, "i0e_r": i0e_r, "weighted": weighted}


def _axis_concentrations(S64: torch.Tensor) -> torch.Tensor:
    """``(..., 3)`` ``(s2 + s3, s1 + s3, s1 + s2)``, the concentrations about the axes."""
    s1, s2, s3 = S64.unbind(-1)
    return torch.stack((s2 + s3, s1 + s3, s1 + s2), dim=-1)


def _large(S64: torch.Tensor) -> torch.Tensor:
    """``(...)`` bool: every axis concentration beyond :data:`_ASYMPTOTIC_FROM`."""
    return _axis_concentrations(S64).amin(-1) > _ASYMPTOTIC_FROM


def _log_j_asymptotic(S64: torch.Tensor) -> torch.Tensor:
    """``log J`` for large concentrations ``κ`` about all three axes: near its mode the density
    is Gaussian, ``J ≈ (8π κ1 κ2 κ3)^(-1/2)``, with a relative error O(1/κ) (< 1e-5 here)."""
    kappa = _axis_concentrations(S64).clamp_min(1.0)
    return -0.5 * math.log(8.0 * math.pi) - 0.5 * torch.log(kappa).sum(-1)


def _log_c_from_terms(S64: torch.Tensor, J: torch.Tensor) -> torch.Tensor:
    log_c = S64.sum(-1) + torch.where(_large(S64), _log_j_asymptotic(S64), torch.log(J))
    small = S64.abs().amax(-1) < _SERIES_LIMIT
    return torch.where(small, _log_c_series(S64), log_c)


def log_normalizer_value(S: torch.Tensor) -> torch.Tensor:
    """``log c`` from proper singular values ``S (..., 3)``, without gradient; dtype of ``S``."""
    S64 = S.detach().to(torch.float64)
    terms = _quadrature_terms(S64)
    return _log_c_from_terms(S64, terms["weighted"].sum(-1)).to(S.dtype)


def log_normalizer_and_expectation(S: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``log c`` and ``E[Q_ii] = d log c / d s_i`` from proper singular values (no autograd).

    Args:
        S: ``(..., 3)`` proper singular values, ``s1 >= s2 >= |s3|``.

    Returns:
        ``log_c (...)`` and ``expected_diagonal (..., 3)``, in the dtype of ``S``.
    """
    S64 = S.detach().to(torch.float64)
    terms = _quadrature_terms(S64)
    weighted, t, tc = terms["weighted"], terms["t"], terms["tc"]
    J = weighted.sum(-1)
    ratio_p = torch.special.i1e(terms["p"] * tc) / terms["i0e_p"] - 1.0
    ratio_r = torch.special.i1e(terms["r"] * t) / terms["i0e_r"] - 1.0
    d_p = (weighted * tc * ratio_p).sum(-1) / J
    d_q = (weighted * (-2.0 * t)).sum(-1) / J
    d_r = (weighted * t * ratio_r).sum(-1) / J
    expected = torch.stack((1.0 + d_p + d_r, 1.0 + d_p + d_q - d_r, 1.0 + d_q), dim=-1)
    # Large concentrations: E[Q_ii] = 1 + d log J / d s_i from the Gaussian limit,
    # 1 - (1/κ_j + 1/κ_k) / 2 with κ the axis concentrations.
    inverse = 1.0 / _axis_concentrations(S64).clamp_min(1.0)
    limit = 1.0 - 0.5 * torch.stack(
        (inverse[..., 1] + inverse[..., 2], inverse[..., 0] + inverse[..., 2],
         inverse[..., 0] + inverse[..., 1]), dim=-1,
    )  # fmt: skip
    expected = torch.where(_large(S64)[..., None], limit, expected)
    return _log_c_from_terms(S64, J).to(S.dtype), expected.to(S.dtype)


class _LogNormalizer(torch.autograd.Function):
    @staticmethod
    def forward(ctx, S: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
        if not ctx.needs_input_grad[0]:
            return log_normalizer_value(S)
        log_c, expected = log_normalizer_and_expectation(S)
        ctx.save_for_backward(expected)
        return log_c

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad_log_c):  # type: ignore[override]
        (expected,) = ctx.saved_tensors
        return grad_log_c.unsqueeze(-1) * expected


def matrix_fisher_log_normalizer(S: torch.Tensor) -> torch.Tensor:
    """``log c(S)`` for proper singular values, differentiable with respect to ``S``.

    Args:
        S: ``(..., 3)`` proper singular values (``s1 >= s2 >= |s3|``), any float dtype.

    Returns:
        ``(...)`` log normalising constant (Haar probability measure, so ``log c(0) = 0``).
        Its gradient is ``E[Q_ii]``, computed by quadrature rather than by autograd.
    """
    if S.shape[-1] != 3:
        raise ValueError(f"expected proper singular values of shape (..., 3), got {tuple(S.shape)}")
    return _LogNormalizer.apply(S)

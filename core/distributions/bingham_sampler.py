"""Rejection sampling of the Bingham distribution on the 3-sphere (Kent, Ganeiber & Mardia 2013).

Target density (with respect to the uniform measure on S^3):
``p(x) ∝ exp(-x^T A x)`` for diagonal ``A = diag(lambda)`` with ``min(lambda) = 0``.
Proposal: the angular central Gaussian ``ACG(Omega)``, ``Omega = I + 2 A / b``, whose density is
``∝ (x^T Omega x)^(-2)``; it is simulated by normalising ``y = Omega^(-1/2) eps``,
``eps ~ N(0, I_4)``. The envelope constant is ``M = exp((b - 4) / 2) (4 / b)^2`` and ``b`` is
Kent's optimal choice, the root of ``sum_i 1 / (b + 2 lambda_i) = 1`` (it lies in [1, 4]).

The accept/reject decision only *selects* noise vectors ``eps``; the accepted ones are then
pushed through the reparameterisation ``x = normalise(Omega^(-1/2) eps)`` once, so samples carry
gradients back to ``lambda``. Everything is vectorised over distributions and samples; the only
loop is over rejection *rounds*, each drawing proposals only for the distributions that still
lack samples (one or two rounds in practice).

With Kent's optimal ``b`` the acceptance probability is 1 for ``A = 0`` and decreases towards
its large-concentration limit ``pi^(3/2) / (16 e^(-3/2) * pi^2 / (2 sqrt 2)) ≈ 0.447``: there the
Bingham is locally Gaussian and the ACG a 3-D Cauchy-like envelope.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

_NEWTON_MAX_ITERATIONS = 50
_NEWTON_TOLERANCE = 1e-13
_ROUND_ACCEPTANCE_GUESS = 0.45
MAX_REJECTION_ROUNDS = 64
"""Rounds after which the rejection loop gives up. Each round is sized for the worst-case
acceptance (~0.447) plus three standard deviations, so even the second round is rare: reaching
this limit means the parameters are broken (e.g. overflowing), never bad luck."""


class SamplerError(ValueError):
    """The rejection sampler cannot draw from these parameters (not finite, or overflowing)."""


@torch.no_grad()
def kent_optimal_b(lambdas: torch.Tensor) -> torch.Tensor:
    """Kent's optimal ACG parameter ``b``: the root in [1, 4] of ``sum_i 1/(b + 2 lambda_i) = 1``.

    Args:
        lambdas: ``(..., 4)`` non-negative Bingham eigenvalues with minimum 0.

    Returns:
        ``(...)`` values of ``b`` in the dtype of ``lambdas`` (no gradient: ``b`` only shapes the
        proposal). Newton's method from ``b = 1`` converges monotonically because the left side
        is convex and decreasing in ``b``; it stops once every residual is below 1e-13.
    """
    two_lambda = 2.0 * lambdas.to(torch.float64)
    b = torch.ones(lambdas.shape[:-1], dtype=torch.float64, device=lambdas.device)
    for _ in range(_NEWTON_MAX_ITERATIONS):
        inv = 1.0 / (b.unsqueeze(-1) + two_lambda)
        residual = inv.sum(-1) - 1.0
        if residual.numel() == 0 or float(residual.abs().max()) < _NEWTON_TOLERANCE:
            break
        b = (b + residual / (inv * inv).sum(-1)).clamp(1.0, 4.0)
    return b.to(lambdas.dtype)


def _round_size(missing: int) -> int:
    """Proposals per row for a round that must yield ``missing`` acceptances.

    Sized for the worst-case acceptance (~0.447) plus three standard deviations, so a second round
    is rare and a third rarer still.
    """
    p = _ROUND_ACCEPTANCE_GUESS
    return math.ceil(missing / p + 3.0 * math.sqrt(missing * (1.0 - p)) / p) + 8


def log_envelope_constant(b: torch.Tensor) -> torch.Tensor:
    """``log M = (b - 4) / 2 + 2 log(4 / b)`` for the ACG envelope (shape of ``b``)."""
    return 0.5 * (b - 4.0) + 2.0 * torch.log(4.0 / b)


@dataclass
class AcceptedNoise:
    """Standard-normal proposal noise that passed the accept/reject test.

    Attributes:
        noise: ``(N, num_samples, 4)`` accepted ``eps`` vectors (no gradient).
        acceptance_rate: ``(N,)`` fraction of proposals accepted for each distribution.
    """

    noise: torch.Tensor
    acceptance_rate: torch.Tensor


@torch.no_grad()
def draw_accepted_noise(
    lambdas: torch.Tensor,
    b: torch.Tensor,
    num_samples: int,
    generator: torch.Generator | None = None,
) -> AcceptedNoise:
    """Run the rejection loop and return exactly ``num_samples`` accepted noise vectors per row.

    Args:
        lambdas: ``(N, 4)`` non-negative diagonal of ``A`` with minimum 0.
        b: ``(N,)`` ACG parameters from :func:`kent_optimal_b`.
        num_samples: accepted samples wanted per distribution (>= 0).
        generator: optional torch random generator.

    Returns:
        :class:`AcceptedNoise`.
    """
    if lambdas.dim() != 2 or lambdas.shape[-1] != 4:
        raise ValueError(f"lambdas must have shape (N, 4), got {tuple(lambdas.shape)}")
    if num_samples < 0:
        raise ValueError(f"num_samples must be >= 0, got {num_samples}")
    lambdas = lambdas.detach()
    bad = ~(torch.isfinite(lambdas).all(-1) & torch.isfinite(b))
    if bool(bad.any()):
        rows = bad.nonzero().flatten().tolist()
        raise SamplerError(
            f"cannot sample: {len(rows)} distribution(s) have non-finite or overflowing "
            f"concentrations (rows {rows[:8]}{' ...' if len(rows) > 8 else ''}); check F for "
            "inf/NaN or values beyond the dtype's range (use float64 for concentrations > 1e30)"
        )
    count = lambdas.shape[0]
    device, dtype = lambdas.device, lambdas.dtype
    inv_omega = 1.0 / (1.0 + 2.0 * lambdas / b.unsqueeze(-1))
    # Columns: weights giving |y|^2 = sum eps^2 / omega and y^T A y = sum lambda eps^2 / omega.
    quadratic_weights = torch.stack((inv_omega, lambdas * inv_omega), dim=-1)  # (N, 4, 2)
    inv_m = torch.exp(-log_envelope_constant(b)).unsqueeze(-1)
    two_over_b = (2.0 / b).unsqueeze(-1)

    accepted = torch.zeros(count * num_samples, 4, device=device, dtype=dtype)
    filled = torch.zeros(count, dtype=torch.long, device=device)
    proposed = torch.zeros(count, dtype=torch.long, device=device)
    accepted_total = torch.zeros(count, dtype=torch.long, device=device)
    rows = torch.arange(count, device=device)
    rounds = 0
    while num_samples > 0 and rows.numel() > 0:
        rounds += 1
        if rounds > MAX_REJECTION_ROUNDS:
            raise SamplerError(
                f"the rejection sampler accepted too few proposals for {rows.numel()} "
                f"distribution(s) in {MAX_REJECTION_ROUNDS} rounds; their parameters are "
                "probably broken (check F for extreme values)"
            )
        round_size = _round_size(int((num_samples - filled[rows]).max()))
        eps = torch.randn(
            rows.numel(), round_size, 4, device=device, dtype=dtype, generator=generator
        )
        y_norm_sq, y_a_y = torch.bmm(eps * eps, quadratic_weights[rows]).unbind(-1)
        x_a_x = y_a_y / y_norm_sq
        # exp(-x^T A x) (x^T Omega x)^2 / M, using x^T Omega x = 1 + (2/b) x^T A x.
        x_omega_x = 1.0 + two_over_b[rows] * x_a_x
        ratio = torch.exp(-x_a_x) * (x_omega_x * x_omega_x) * inv_m[rows]
        uniform = torch.rand(
            rows.numel(), round_size, device=device, dtype=dtype, generator=generator
        )
        accept = uniform < ratio
        slot = torch.cumsum(accept, dim=1) - 1 + filled[rows].unsqueeze(-1)
        take = accept & (slot < num_samples)
        # Copy the accepted noise to its output slot, using flat indices (fast index_copy_).
        source = take.view(-1).nonzero().squeeze(-1)
        target = rows[source // round_size] * num_samples + slot.view(-1)[source]
        accepted.index_copy_(0, target, eps.view(-1, 4).index_select(0, source))
        proposed[rows] += round_size
        accepted_total[rows] += accept.sum(1)
        filled[rows] += take.sum(1)
        rows = rows[filled[rows] < num_samples]
    accepted = accepted.view(count, num_samples, 4)
    acceptance = accepted_total.to(dtype) / proposed.clamp_min(1).to(dtype)
    return AcceptedNoise(noise=accepted, acceptance_rate=acceptance)


def proposal_transform(
    lambdas: torch.Tensor,
    b: torch.Tensor,
    noise: torch.Tensor,
    orthogonal_map: torch.Tensor | None = None,
) -> torch.Tensor:
    """The ACG reparameterisation ``x = normalise(P Omega^(-1/2) eps)``, differentiable.

    Args:
        lambdas: ``(N, 4)`` Bingham eigenvalues (may require grad).
        b: ``(N,)`` ACG parameters from :func:`kent_optimal_b`.
        noise: ``(N, K, 4)`` standard-normal noise.
        orthogonal_map: optional ``(N, 4, 4)`` orthogonal ``P`` applied to the samples (it
            commutes with normalisation); identity when None. The matrix-Fisher sampler uses it
            to move quaternions into the frames of ``U`` and ``V`` with one small product.

    Returns:
        ``(N, K, 4)`` unit vectors.
    """
    scale = torch.rsqrt(1.0 + 2.0 * lambdas / b.unsqueeze(-1))  # (N, 4)
    if orthogonal_map is None:
        y = noise * scale.unsqueeze(1)
    else:
        # y_k = P diag(scale) eps_k for every k, i.e. y = eps @ (diag(scale) P^T).
        y = torch.bmm(noise, scale.unsqueeze(-1) * orthogonal_map.transpose(-1, -2))
    return y / torch.linalg.vector_norm(y, dim=-1, keepdim=True)


@dataclass
class BinghamSamples:
    """Result of :func:`sample_bingham`.

    Attributes:
        quaternions: ``(N, num_samples, 4)`` unit vectors on S^3, ordered like ``lambdas``.
        acceptance_rate: ``(N,)`` fraction of proposals accepted for each distribution.
    """

    quaternions: torch.Tensor
    acceptance_rate: torch.Tensor


def sample_bingham(
    lambdas: torch.Tensor, num_samples: int, generator: torch.Generator | None = None
) -> BinghamSamples:
    """Draw exactly ``num_samples`` reparameterised Bingham samples for each of N distributions.

    Args:
        lambdas: ``(N, 4)`` non-negative diagonal of ``A`` with minimum 0; may require grad.
        num_samples: samples per distribution (>= 0).
        generator: optional torch random generator for reproducibility.

    Returns:
        :class:`BinghamSamples` with quaternions of shape ``(N, num_samples, 4)``.
    """
    b = kent_optimal_b(lambdas)
    drawn = draw_accepted_noise(lambdas, b, num_samples, generator)
    return BinghamSamples(proposal_transform(lambdas, b, drawn.noise), drawn.acceptance_rate)

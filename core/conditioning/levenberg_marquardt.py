"""A batched Levenberg-Marquardt solver for small robust least-squares problems.

B independent problems (the fit's starts) advance together. Each iteration evaluates the
residuals at the current estimate and at 85 forward-difference perturbations in one batched
call (float64, step 1e-6: the Jacobian is accurate to ~1e-6 relative, and one batched body
evaluation is ~5× cheaper than forward-mode autodiff here), re-weights the keypoint residuals
with the Cauchy loss (IRLS), and solves the damped normal equations

    (JᵀJ + λ diag(JᵀJ)) Δ = -Jᵀr.

Marquardt's diagonal scaling makes the step invariant to each variable's units, so a hand joint
whose prior concentration is 1e8 and a knee at 1e2 are treated alike (neither stalls the other).
Steps that do not lower the robust cost are rejected and λ grows; accepted ones shrink it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from hkpd.conditioning.fit_residuals import NUM_PARAMETERS, FitState, Residuals

FINITE_DIFFERENCE_STEP = 1e-6
_INITIAL_DAMPING = 1e-3
_MAX_DAMPING = 1e10
_ABSOLUTE_DAMPING = 1e-9


@dataclass(frozen=True)
class SolverResult:
    """What :func:`levenberg_marquardt` found, per start.

    Attributes:
        state: the estimate, leading dim ``(B,)``.
        cost: ``(B,)`` final robust cost ``½ Σ ρ(e²) + ½ |r_prior|²``.
        initial_cost: ``(B,)`` the start's cost.
        hessian: ``(B, 85, 85)`` Gauss-Newton Hessian ``JᵀWJ`` at the estimate (IRLS weights).
        keypoint_weights: ``(B, 17)`` IRLS weights at the estimate (1 = fully trusted).
        iterations: iterations run.
        converged: ``(B,)`` bool, the relative cost decrease fell below the tolerance (or the
            damping saturated at a minimum).
    """

    state: FitState
    cost: torch.Tensor
    initial_cost: torch.Tensor
    hessian: torch.Tensor
    keypoint_weights: torch.Tensor
    iterations: int
    converged: torch.Tensor


def cauchy_cost(squared: torch.Tensor, scale: float) -> torch.Tensor:
    """``½ c² log(1 + e²/c²)`` elementwise (``≈ ½ e²`` for small ``e``)."""
    c2 = scale * scale
    return 0.5 * c2 * torch.log1p(squared / c2)


def cauchy_weight(squared: torch.Tensor, scale: float) -> torch.Tensor:
    """IRLS weight ``1 / (1 + e²/c²)`` of the Cauchy loss."""
    return 1.0 / (1.0 + squared / (scale * scale))


def robust_cost(residuals: Residuals, scale: float) -> torch.Tensor:
    """``(N, B)`` the robust cost of each evaluated state."""
    keypoints = cauchy_cost(residuals.squared_keypoint_errors(), scale).sum(-1)
    return keypoints + 0.5 * residuals.priors.square().sum(-1)


def _linearise(
    residual_fn: Callable[[FitState], Residuals], state: FitState, scale: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Cost ``(B,)``, gradient ``(B, 85)``, Hessian ``(B, 85, 85)`` and IRLS weights ``(B, 17)``."""
    batch = state.betas.shape[0]
    dtype, device = state.betas.dtype, state.betas.device
    steps = torch.zeros(NUM_PARAMETERS + 1, batch, NUM_PARAMETERS, dtype=dtype, device=device)
    index = torch.arange(NUM_PARAMETERS, device=device)
    steps[index + 1, :, index] = FINITE_DIFFERENCE_STEP
    evaluated = residual_fn(state.retract(steps))
    weights = cauchy_weight(evaluated.squared_keypoint_errors()[0], scale)
    stacked = evaluated.stacked(weights)  # (86, B, M)
    base = stacked[0]
    jacobian = ((stacked[1:] - base) / FINITE_DIFFERENCE_STEP).permute(1, 2, 0)  # (B, M, 85)
    gradient = (jacobian.transpose(1, 2) @ base.unsqueeze(-1)).squeeze(-1)
    hessian = jacobian.transpose(1, 2) @ jacobian
    cost = robust_cost(Residuals(evaluated.keypoints[:1], evaluated.priors[:1]), scale)[0]
    return cost, gradient, hessian, weights


def levenberg_marquardt(
    residual_fn: Callable[[FitState], Residuals],
    start: FitState,
    *,
    robust_scale: float,
    max_iterations: int,
    tolerance: float,
) -> SolverResult:
    """Minimise the robust cost of ``residual_fn`` from ``start`` (B problems at once).

    Args:
        residual_fn: maps a state with leading dims ``(N, B)`` to its :class:`Residuals`.
        start: leading dim ``(B,)``.
        robust_scale: the Cauchy loss's scale, in sigmas.
        max_iterations: at most this many iterations.
        tolerance: relative cost decrease below which a start counts as converged.
    """
    state = start
    cost, gradient, hessian, weights = _linearise(residual_fn, state, robust_scale)
    initial_cost = cost
    batch = cost.shape[0]
    damping = torch.full_like(cost, _INITIAL_DAMPING)
    converged = torch.zeros(batch, dtype=torch.bool, device=cost.device)
    eye = torch.eye(NUM_PARAMETERS, dtype=cost.dtype, device=cost.device)
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (reported after the loop)
        diagonal = hessian.diagonal(dim1=-2, dim2=-1)
        damped = hessian + torch.diag_embed(damping[:, None] * diagonal) + _ABSOLUTE_DAMPING * eye
        step = torch.linalg.solve(damped, -gradient.unsqueeze(-1)).squeeze(-1)
        step = torch.where(converged[:, None], torch.zeros_like(step), step)
        candidate = state.retract(step[None])
        candidate_cost = robust_cost(residual_fn(candidate), robust_scale)[0]
        better = torch.isfinite(candidate_cost) & (candidate_cost < cost) & ~converged
        decrease = (cost - candidate_cost) / cost.clamp_min(1e-12)
        converged |= better & (decrease < tolerance)
        damping = torch.where(better, damping / 3.0, damping * 4.0)
        converged |= damping > _MAX_DAMPING
        if better.any():
            state = candidate.copy(0).select(better, state)
            cost, gradient, hessian, weights = _relinearise(
                residual_fn, state, robust_scale, better, (cost, gradient, hessian, weights)
            )
        if bool(converged.all()):
            break
    return SolverResult(state, cost, initial_cost, hessian, weights, iterations, converged)


def _relinearise(
    residual_fn: Callable[[FitState], Residuals],
    state: FitState,
    scale: float,
    changed: torch.Tensor,
    previous: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Linearise again, keeping the previous values for starts that did not move."""
    fresh = _linearise(residual_fn, state, scale)
    return tuple(
        torch.where(changed.reshape(-1, *([1] * (new.dim() - 1))), new, old)
        for new, old in zip(fresh, previous, strict=True)
    )  # type: ignore[return-value]

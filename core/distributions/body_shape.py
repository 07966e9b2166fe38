"""The diagonal Gaussian over body-shape coefficients (the paper's Eq. 3)."""

from __future__ import annotations

import torch
from torch.distributions import Independent, Normal


def body_shape_distribution(mean: torch.Tensor, std: torch.Tensor) -> Independent:
    """``N(beta; mean, diag(std^2))`` as a torch distribution with event shape ``(10,)``.

    Args:
        mean: ``(..., num_betas)`` shape-coefficient means (dimensionless PCA units).
        std: ``(..., num_betas)`` positive standard deviations.

    Returns:
        ``Independent(Normal(mean, std), 1)``: ``rsample`` is reparameterised and ``log_prob``
        sums over the coefficients.
    """
    return Independent(Normal(mean, std), 1)

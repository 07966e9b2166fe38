"""The body-shape Gaussian is torch's own Normal, wrapped to an event of 10 coefficients."""

from __future__ import annotations

import torch
from torch.distributions import Normal

from hkpd.distributions import body_shape_distribution


def test_log_prob_and_reparameterised_samples() -> None:
    mean = torch.randn(4, 10, requires_grad=True)
    std = torch.rand(4, 10) + 0.1
    distribution = body_shape_distribution(mean, std)
    assert distribution.event_shape == (10,) and distribution.batch_shape == (4,)
    beta = torch.randn(4, 10)
    assert torch.allclose(distribution.log_prob(beta), Normal(mean, std).log_prob(beta).sum(-1))
    distribution.rsample((6,)).sum().backward()
    assert mean.grad is not None and torch.allclose(mean.grad, torch.full_like(mean, 6.0))

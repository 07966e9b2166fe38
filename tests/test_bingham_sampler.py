"""Kent's rejection sampler for the Bingham distribution on S^3."""

from __future__ import annotations

import torch

from hkpd.distributions import MatrixFisher, kent_optimal_b, sample_bingham


def test_kent_b_solves_its_equation() -> None:
    lambdas = torch.tensor(
        [[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 2.0, 3.0], [0.0, 1e3, 1e3, 1e3], [0.0, 0.0, 4e5, 4e5]],
        dtype=torch.float64,
    )
    b = kent_optimal_b(lambdas)
    residual = (1.0 / (b[:, None] + 2.0 * lambdas)).sum(-1) - 1.0
    assert torch.allclose(residual, torch.zeros_like(residual), atol=1e-12)
    assert abs(float(b[0]) - 4.0) < 1e-12 and ((b >= 1.0) & (b <= 4.0)).all()


def test_returns_exactly_the_requested_unit_samples() -> None:
    lambdas = torch.tensor([[0.0, 0.0, 0.0, 0.0], [0.0, 5.0, 50.0, 500.0], [0.0, 1.0, 1.0, 1e4]])
    for count in (0, 1, 7, 333):
        drawn = sample_bingham(lambdas, count, generator=torch.Generator().manual_seed(count))
        assert drawn.quaternions.shape == (3, count, 4)
        norms = torch.linalg.vector_norm(drawn.quaternions, dim=-1)
        assert torch.allclose(norms, torch.ones_like(norms), atol=1e-6)
    assert drawn.acceptance_rate[0] == 1.0  # A = 0: the proposal is the target


def test_acceptance_rate_matches_theory_and_stays_above_kent_limit() -> None:
    torch.manual_seed(3)
    scales = torch.tensor([0.0, 0.1, 1.0, 10.0, 100.0, 1000.0])
    F = torch.randn(scales.numel(), 3, 3) * scales[:, None, None]
    distribution = MatrixFisher(F.double())
    distribution.sample((20000,), generator=torch.Generator().manual_seed(4))
    achieved = distribution.last_acceptance_rate
    expected = distribution.expected_acceptance_rate
    assert torch.allclose(achieved, expected, atol=0.015)
    # Kent's envelope with optimal b tends to ~0.4468 as the concentration grows.
    assert (expected >= 0.446).all()


def test_sampling_is_reproducible_with_a_generator() -> None:
    lambdas = torch.tensor([[0.0, 3.0, 4.0, 5.0]])
    first = sample_bingham(lambdas, 50, generator=torch.Generator().manual_seed(7)).quaternions
    second = sample_bingham(lambdas, 50, generator=torch.Generator().manual_seed(7)).quaternions
    assert torch.equal(first, second)

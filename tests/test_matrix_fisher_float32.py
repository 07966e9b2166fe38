"""float32 matrix-Fisher densities hold at the shipped model's concentrations (up to 1e8)."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.distributions import MatrixFisher
from hkpd.evaluation.calibration import truth_rank

CONCENTRATIONS = [1e1, 1e3, 1e5, 1e6, 1e7, 1e8]


def _pair(s: float) -> tuple[MatrixFisher, MatrixFisher]:
    generator = torch.Generator().manual_seed(int(s) % 1000)
    U = roma.rotvec_to_rotmat(torch.randn(3, generator=generator, dtype=torch.float64))
    V = roma.rotvec_to_rotmat(torch.randn(3, generator=generator, dtype=torch.float64))
    S = torch.tensor([s, 0.7 * s, 0.4 * s], dtype=torch.float64)
    F32 = (U @ torch.diag(S) @ V.T).float()
    return MatrixFisher(F32[None]), MatrixFisher(F32.double()[None])  # the same F, two dtypes


@pytest.mark.parametrize("s", CONCENTRATIONS)
def test_float32_log_prob_entropy_and_acceptance_match_float64(s: float) -> None:
    low, high = _pair(s)
    mode = high.mode
    near = mode @ roma.rotvec_to_rotmat(torch.tensor([[1.0, -2.0, 0.5]], dtype=torch.float64)
                                        / s**0.5)  # fmt: skip
    for rotation in (mode, near):
        got = low.log_prob(rotation.float())
        assert got.dtype == torch.float32
        assert abs(float(got) - float(high.log_prob(rotation))) < 0.05
    assert abs(float(low.entropy()) - float(high.entropy())) < 0.05
    assert abs(float(low.expected_acceptance_rate) - float(high.expected_acceptance_rate)) < 1e-3


def test_log_prob_keeps_the_training_gradient() -> None:
    F = (torch.eye(3) * 5).requires_grad_()
    rotation = roma.rotvec_to_rotmat(torch.tensor([0.3, 0.1, -0.2]))
    MatrixFisher(F[None]).log_prob(rotation[None]).sum().backward()
    expected = rotation - MatrixFisher(F.detach()[None]).mean[0]  # d/dF = R - E[R]
    torch.testing.assert_close(F.grad, expected, rtol=1e-4, atol=1e-5)


def test_float32_coverage_ranks_match_float64_at_high_concentration() -> None:
    low, high = _pair(1e7)
    generator = torch.Generator().manual_seed(0)
    samples = high.sample((400,), generator=generator)  # (400, 1, 3, 3)
    truth = high.sample((1,), generator=generator)[0]
    F32, F64 = low.F[None], high.F[None]  # (B=1, J=1, 3, 3)
    rank32 = truth_rank(F32, samples.float()[:, None], truth.float()[None])
    rank64 = truth_rank(F64, samples[:, None], truth[None])
    assert abs(float(rank32) - float(rank64)) <= 0.02

"""The rejection sampler never hangs: broken parameters raise a clear error at once."""

from __future__ import annotations

import math

import pytest
import torch

from hkpd.distributions import KinematicMatrixFisher, MatrixFisher
from hkpd.distributions.bingham_sampler import SamplerError, draw_accepted_noise, kent_optimal_b
from hkpd.kinematic_tree import BODY_PARENTS


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_non_finite_F_raises_instead_of_hanging(value) -> None:
    F = torch.eye(3).expand(4, 3, 3).clone() * 5
    F[2, 0, 0] = value
    with pytest.raises(SamplerError, match="inf or NaN"):
        MatrixFisher(F, validate_args=False).sample((10,))


def test_overflowing_float32_concentration_raises() -> None:
    F = torch.eye(3) * 3e38  # finite, but the Bingham eigenvalues overflow to inf
    with pytest.raises(SamplerError, match="non-finite or overflowing"):
        MatrixFisher(F[None]).sample((5,))


def test_one_bad_joint_fails_the_batch_with_a_message_not_a_hang() -> None:
    F = torch.eye(3).expand(2, 23, 3, 3).clone() * 10
    F[1, 7] = math.inf
    with pytest.raises(SamplerError):
        KinematicMatrixFisher(F, BODY_PARENTS).sample(3)


def test_a_proposal_that_never_accepts_stops_after_the_round_limit() -> None:
    lambdas = torch.tensor([[1.0, 2.0, 3.0, 0.0]])
    b = kent_optimal_b(lambdas) * 0 + 1e-30  # a (broken) envelope that accepts nothing
    with pytest.raises(SamplerError, match="rounds"):
        draw_accepted_noise(lambdas, b, 5)

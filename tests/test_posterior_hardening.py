"""BodyPosterior and the distributions refuse nonsense clearly and work in bounded memory."""

from __future__ import annotations

import math

import pytest
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher, MatrixFisher
from hkpd.kinematic_tree import BODY_PARENTS
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import BodyPosterior


@pytest.fixture(scope="module")
def posterior() -> BodyPosterior:
    generator = torch.Generator().manual_seed(0)
    F = 30.0 * torch.eye(3).expand(23, 3, 3) + torch.randn(23, 3, 3, generator=generator)
    distribution = BodyDistribution(
        F,
        torch.zeros(10),
        torch.ones(10) * 0.3,
        FRONTAL_GLOBAL_ORIENT.clone(),
        torch.tensor([0.9, 0.0, 0.0]),
    )
    return BodyPosterior(
        distribution=distribution,
        crop=CropTransform((100.0, 100.0), 200.0, 128), keypoints=torch.zeros(17, 2),
        confidences=torch.ones(17), body=BodyModel(),
    )  # fmt: skip


@pytest.mark.parametrize("factor", [math.nan, math.inf, -1.0, 0.0])
def test_bad_factors_are_refused_with_our_message(posterior, factor) -> None:
    with pytest.raises(ValueError, match="finite number > 0"):
        posterior.with_shape_std(factor)
    with pytest.raises(ValueError, match="finite number > 0"):
        posterior.with_concentration("left_elbow", factor)


def test_a_bool_is_not_a_joint(posterior) -> None:
    with pytest.raises(TypeError, match="joint"):
        posterior.with_concentration(True, 2.0)
    with pytest.raises(TypeError, match="joints"):
        posterior.with_concentration([0, False], 2.0)
    with pytest.raises(TypeError, match="number"):
        posterior.with_concentration(0, "2")


def test_nan_scale_factors_are_refused_by_the_tree_distribution() -> None:
    tree = KinematicMatrixFisher(torch.eye(3).expand(1, 23, 3, 3) * 5, BODY_PARENTS)
    with pytest.raises(ValueError, match="finite"):
        tree.scale_concentration([1], math.nan)


def test_chunked_uncertainty_equals_the_unchunked_one(posterior) -> None:
    whole = posterior.vertex_uncertainty(60, seed=3, chunk=60)
    chunked = posterior.vertex_uncertainty(60, seed=3, chunk=16)
    torch.testing.assert_close(chunked, whole, rtol=1e-5, atol=1e-7)
    with pytest.raises(ValueError, match="chunk"):
        posterior.vertex_uncertainty(10, chunk=0)
    with pytest.raises(ValueError, match="samples"):
        posterior.sample(0)


@pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16])
def test_half_precision_F_is_computed_in_float32(dtype) -> None:
    F = (torch.eye(3) * 20).to(dtype)[None]
    distribution = MatrixFisher(F)
    samples = distribution.sample((5,))
    assert samples.dtype == torch.float32 and torch.isfinite(samples).all()
    assert torch.isfinite(distribution.log_prob(samples)).all()

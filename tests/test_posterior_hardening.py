"""BodyPosterior and the distributions refuse nonsense clearly and work in bounded memory."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher, MatrixFisher
from hkpd.kinematic_tree import BODY_JOINT_NAMES, BODY_PARENTS
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import MAX_CONCENTRATION, MAX_SHAPE_STD, BodyPosterior


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


@pytest.mark.parametrize(
    "factor",
    [2, 2.0, np.float32(2.0), np.float64(2.0), np.int64(2), np.array(2.0), np.array(2),
     torch.tensor(2.0), torch.tensor(2), torch.tensor([2.0]), np.float16(2.0)],
)  # fmt: skip
def test_every_real_number_type_is_a_factor(posterior, factor) -> None:
    torch.testing.assert_close(posterior.with_shape_std(factor).shape_std, posterior.shape_std * 2)
    scaled = posterior.with_concentration("left_elbow", factor)
    index = BODY_JOINT_NAMES.index("left_elbow")
    torch.testing.assert_close(
        scaled.pose_distribution.joints.S[0, index],
        posterior.pose_distribution.joints.S[0, index] * 2,
    )


@pytest.mark.parametrize(
    "factor",
    [True, np.bool_(True), 2 + 0j, np.complex128(2.0), torch.tensor(True), torch.tensor(2 + 0j),
     np.array([2.0, 3.0]), torch.tensor([2.0, 3.0]), "2", None],
)  # fmt: skip
def test_bools_complex_numbers_and_non_scalars_are_not_factors(posterior, factor) -> None:
    with pytest.raises(TypeError, match="real number"):
        posterior.with_shape_std(factor)
    with pytest.raises(TypeError, match="real number"):
        posterior.with_concentration(None, factor)


@pytest.mark.parametrize(
    "call",
    [
        lambda p: p.with_shape_std(1e30),
        lambda p: p.with_shape_std(1e300),
        lambda p: p.with_shape_std(10**400),
        lambda p: p.with_shape_std(np.float32(3e38)),
        lambda p: p.with_concentration(None, 1e300),
        lambda p: p.with_concentration("left_elbow", 1e40),
        lambda p: p.with_concentration(None, 1e6).with_concentration(None, 1e6),
        lambda p: p.with_shape_std(1e4).with_shape_std(1e4),
    ],
)
def test_a_factor_that_would_overflow_is_refused_stating_the_range(posterior, call) -> None:
    with pytest.raises(ValueError) as caught:
        call(posterior)
    message = str(caught.value)
    assert "finite number > 0 and at most" in message, message
    assert f"{MAX_SHAPE_STD:g}" in message or f"{MAX_CONCENTRATION:g}" in message, message


def test_large_factors_inside_the_range_keep_the_uncertainty_finite(posterior) -> None:
    largest_std = float(posterior.shape_std.max())
    widened = posterior.with_shape_std(0.99 * MAX_SHAPE_STD / largest_std)
    largest_s = float(posterior.pose_distribution.joints.S.abs().max())
    sharpened = widened.with_concentration(None, 0.99 * MAX_CONCENTRATION / largest_s)
    uncertainty = sharpened.vertex_uncertainty(8, seed=0)
    assert torch.isfinite(uncertainty).all() and float(uncertainty.max()) > 1.0

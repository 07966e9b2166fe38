"""Tests for hkpd.evaluation.metrics and alignment on hand-made cases."""

from __future__ import annotations

import math

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.evaluation import (
    MILLIMETRES_PER_METRE,
    joint_error_2d,
    min_of_n,
    mpjpe,
    mpjpe_procrustes,
    mpjpe_scale_corrected,
    per_joint_spread,
    procrustes_align,
    pve_t_sc,
    pve_t_sc_from_betas,
    rms_scale_align,
    sample_diversity,
)


@pytest.fixture
def joints() -> torch.Tensor:
    return torch.randn(5, 24, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)


def test_mpjpe_ignores_translation_and_measures_offsets(joints):
    shifted = joints + torch.tensor([0.3, -1.0, 4.0], dtype=torch.float64)
    torch.testing.assert_close(mpjpe(shifted, joints), torch.zeros(5, dtype=torch.float64))
    # Moving one non-root joint by 0.024 m: mean error 0.024 / 24 = 1 mm.
    moved = joints.clone()
    moved[:, 7, 0] += 0.024
    torch.testing.assert_close(mpjpe(moved, joints) * MILLIMETRES_PER_METRE, torch.ones(5).double())


def test_procrustes_removes_similarity_transform(joints):
    rotation = roma.random_rotmat(5, dtype=torch.float64)
    transformed = 2.5 * joints @ rotation.transpose(1, 2) + torch.randn(5, 1, 3).double()
    assert mpjpe(transformed, joints).min() > 0.1
    torch.testing.assert_close(mpjpe_procrustes(transformed, joints), torch.zeros(5).double())
    torch.testing.assert_close(procrustes_align(transformed, joints), joints)


def test_procrustes_never_reflects(joints):
    mirrored = joints * torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64)
    aligned = procrustes_align(mirrored, joints)
    # A reflection is not a similarity transform in SO(3): the error must stay positive.
    assert mpjpe_procrustes(mirrored, joints).min() > 1e-3
    # ...but the aligned result is still a rotated, scaled copy (distances scale uniformly).
    ratio = torch.cdist(aligned, aligned)[:, 0, 1:] / torch.cdist(mirrored, mirrored)[:, 0, 1:]
    torch.testing.assert_close(ratio, ratio[:, :1].expand_as(ratio))


@pytest.mark.parametrize("method", ["rms", "least_squares"])
def test_scale_correction_removes_scale_not_rotation(joints, method):
    scaled = 0.6 * joints + torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64)
    torch.testing.assert_close(
        mpjpe_scale_corrected(scaled, joints, method=method), torch.zeros(5).double()
    )
    rotation = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.5, 0.0], dtype=torch.float64))
    rotated = joints @ rotation.T
    assert mpjpe_scale_corrected(rotated, joints, method=method).min() > 0.05
    with pytest.raises(ValueError, match="method"):
        mpjpe_scale_corrected(joints, joints, method="median")


def test_rms_scale_align_matches_centroid_and_spread(joints):
    predicted = 3.0 * joints.flip(1) * torch.tensor([1.0, 2.0, 0.5]).double() + 1.0
    aligned = rms_scale_align(predicted, joints)
    torch.testing.assert_close(aligned.mean(1), joints.mean(1))
    spread = (aligned - aligned.mean(1, keepdim=True)).square().sum((1, 2))
    target_spread = (joints - joints.mean(1, keepdim=True)).square().sum((1, 2))
    torch.testing.assert_close(spread, target_spread)


def test_pve_t_sc_with_the_body_model():
    body = BodyModel()
    betas = torch.randn(3, 10, generator=torch.Generator().manual_seed(1))
    torch.testing.assert_close(pve_t_sc_from_betas(body, betas, betas), torch.zeros(3))
    other = betas.clone()
    other[:, 0] += 2.0
    error = pve_t_sc_from_betas(body, other, betas)
    assert (error > 1e-3).all()  # a 2-sigma change of the first coefficient moves the mesh
    vertices = body.tpose(betas)
    torch.testing.assert_close(
        pve_t_sc(vertices * 1.1, vertices), torch.zeros(3), atol=1e-6, rtol=0
    )


def test_joint_error_2d_counts_visible_joints_only():
    target = torch.zeros(2, 17, 2)
    predicted = target.clone()
    predicted[:, 0] = torch.tensor([3.0, 4.0])  # 5 px off, visible
    predicted[:, 1] = torch.tensor([300.0, 0.0])  # far off, invisible
    visible = torch.ones(2, 17, dtype=torch.bool)
    visible[:, 1] = False
    visible[1] = False  # the second example has nothing visible
    error = joint_error_2d(predicted, target, visible)
    assert error[0].item() == pytest.approx(5.0 / 16)
    assert math.isnan(error[1].item())


def test_joint_error_2d_averages_samples():
    target = torch.zeros(1, 17, 2)
    samples = torch.zeros(2, 1, 17, 2)
    samples[0, :, :, 0] = 2.0
    samples[1, :, :, 0] = 4.0
    visible = torch.ones(1, 17, dtype=torch.bool)
    assert joint_error_2d(samples, target, visible).item() == pytest.approx(3.0)


def test_min_of_n_takes_minimum_over_first_n():
    errors = torch.tensor([[5.0, 1.0], [4.0, 9.0], [3.0, 9.0], [1.0, 0.5], [2.0, 0.1]])
    result = min_of_n(errors, counts=(1, 3, 5))
    torch.testing.assert_close(result[1], torch.tensor([5.0, 1.0]))
    torch.testing.assert_close(result[3], torch.tensor([3.0, 1.0]))
    torch.testing.assert_close(result[5], torch.tensor([1.0, 0.1]))
    with pytest.raises(ValueError, match="min-of-10 needs at least 10 samples"):
        min_of_n(errors)


def test_sample_diversity_zero_for_identical_samples_and_split_by_visibility():
    points = torch.randn(1, 2, 17, 3).expand(10, 2, 17, 3)
    visible = torch.zeros(2, 17, dtype=torch.bool)
    visible[:, :9] = True
    diversity = sample_diversity(points, visible)
    torch.testing.assert_close(diversity["visible"], torch.zeros(2))
    torch.testing.assert_close(diversity["invisible"], torch.zeros(2))

    # Invisible joints spread +-0.1 m along x: mean distance from the mean is 0.1 m.
    spread_points = points.clone()
    spread_points[:5, :, 9:, 0] += 0.1
    spread_points[5:, :, 9:, 0] -= 0.1
    diversity = sample_diversity(spread_points, visible)
    torch.testing.assert_close(diversity["visible"], torch.zeros(2))
    torch.testing.assert_close(diversity["invisible"], torch.full((2,), 0.1))
    assert per_joint_spread(spread_points).shape == (2, 17)


def test_bad_shapes_are_rejected():
    with pytest.raises(ValueError, match=r"\(B, N, 3\)"):
        mpjpe_procrustes(torch.zeros(2, 5, 3), torch.zeros(2, 6, 3))
    with pytest.raises(ValueError, match="visible"):
        sample_diversity(torch.zeros(3, 2, 17, 3), torch.ones(2, 16, dtype=torch.bool))

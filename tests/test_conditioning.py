"""The keypoint-evidence posterior: the fit, the Laplace map back to the families, fallbacks."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import (
    EvidenceConfig,
    KeypointEvidence,
    condition_on_keypoints,
    marginal_precisions,
    matrix_fisher_from_precision,
)
from hkpd.conditioning.laplace import matrix_fisher_precision
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher, MatrixFisher
from hkpd.evaluation.occlusion_response import limb_vertex_masks
from hkpd.kinematic_tree import BODY_PARENTS, body_joint_index
from hkpd.prediction.readings.upright_view import UprightView, torso_tilt
from hkpd.uncertainty import vertex_uncertainty

SIZE = 128
LEFT_WRIST, LEFT_KNEE, LEFT_ANKLE = 9, 13, 15


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


@pytest.fixture(scope="module")
def body64(body) -> BodyModel:
    return BodyModel().double()


@pytest.fixture(scope="module")
def scene(body64):
    """A posed body, its exact crop keypoints, and a prior centred 0.15 rad away from it."""
    generator = torch.Generator().manual_seed(3)
    true_pose = roma.rotvec_to_rotmat(0.35 * torch.randn(23, 3, generator=generator).double())
    orient = FRONTAL_GLOBAL_ORIENT.double()
    camera = torch.tensor([0.95, 0.02, 0.05], dtype=torch.float64)
    betas = 0.5 * torch.randn(1, 10, generator=generator).double()
    keypoints = _project(body64, true_pose, orient, camera, betas)
    offset = roma.rotvec_to_rotmat(0.15 * torch.randn(23, 3, generator=generator).double())
    prior_mode = true_pose @ offset
    F = 10.0 * prior_mode  # concentration 20 about every axis (std ~13°)
    start = BodyDistribution(F[None], torch.zeros(1, 10).double(), torch.ones(1, 10).double(),
                         orient[None], torch.tensor([[0.9, 0.0, 0.0]]).double())  # fmt: skip
    return {"pose": true_pose, "keypoints": keypoints, "start": start, "betas": betas}


def _project(body, pose, orient, camera, betas) -> torch.Tensor:
    keypoints, joints = body.posed_keypoints(betas, pose[None], orient[None])
    relative = keypoints[0] - joints[0, :1]
    return ndc_to_pixels(camera[0] * (relative[:, :2] + camera[1:]), SIZE)


def _evidence(scene, hidden=()) -> KeypointEvidence:
    observed = torch.ones(17, dtype=torch.bool)
    observed[list(hidden)] = False
    return KeypointEvidence(scene["keypoints"], observed, SIZE)


def _reprojection(body64, fit, scene) -> torch.Tensor:
    c = fit.conditioned
    pose = KinematicMatrixFisher(c.F[None], BODY_PARENTS).mode[0]
    points = _project(body64, pose, c.global_orient, c.camera, c.shape_mean[None])
    return (points - scene["keypoints"]).norm(dim=-1)


def test_fit_to_a_bodys_exact_keypoints_recovers_it(body64, scene) -> None:
    config = EvidenceConfig(prior_weight=0.01)
    fit = condition_on_keypoints(body64, scene["start"], _evidence(scene), config)
    assert fit.succeeded and fit.reason == ""
    start_error = (
        _project(
            body64,
            scene["start"].F[0] / 10.0,
            FRONTAL_GLOBAL_ORIENT.double(),
            scene["start"].camera[0],
            torch.zeros(1, 10).double(),
        )
        - scene["keypoints"]
    ).norm(dim=-1)
    error = _reprojection(body64, fit, scene)
    assert start_error.mean() > 3.0  # the start is visibly off ...
    assert error.mean() < 0.3 and error.max() < 1.0  # ... the fit lands on the keypoints
    assert fit.costs[0] < fit.initial_costs[0]
    assert fit.keypoint_weights.min() > 0.99  # no keypoint treated as an outlier


def test_removing_a_keypoint_returns_its_joints_concentration_to_the_prior(body64, scene) -> None:
    config = EvidenceConfig(prior_weight=0.3)
    elbow = body_joint_index("left_elbow")
    # untempered: nothing reads the elbow once the wrist is hidden (issue 58, evidence_reach)
    prior = MatrixFisher(scene["start"].F[0, elbow]).concentration
    seen = condition_on_keypoints(body64, scene["start"], _evidence(scene), config)
    unseen = condition_on_keypoints(body64, scene["start"], _evidence(scene, [LEFT_WRIST]), config)
    with_wrist = MatrixFisher(seen.conditioned.F[elbow]).concentration
    without = MatrixFisher(unseen.conditioned.F[elbow]).concentration
    # The wrist sharpens the elbow about the axis that moves it in the image (depth and twist
    # stay with the prior); without it the elbow is back at the prior's concentrations.
    assert with_wrist.max() > 1.25 * config.prior_weight * prior.max()
    torch.testing.assert_close(without.sort().values, prior.sort().values, rtol=0.2, atol=0)


@pytest.mark.parametrize(
    ("rigid_spread", "hidden_ratio"),
    # The default marginalises the camera for the shape: the honest (wider) height spread
    # reaches every vertex alike, so the hidden shin's share of the spread is smaller.
    [("conditional", 1.2), ("shape", 1.1)],
)
def test_evidence_shrinks_the_samples_spread_and_a_hidden_limb_spreads(
    body, body64, scene, rigid_spread, hidden_ratio
):
    config = EvidenceConfig(rigid_spread=rigid_spread)
    full = condition_on_keypoints(body64, scene["start"], _evidence(scene), config)
    covered = condition_on_keypoints(
        body64, scene["start"], _evidence(scene, [LEFT_KNEE, LEFT_ANKLE]), config
    )

    def uncertainty(F, betas_mean, betas_std) -> torch.Tensor:
        generator = torch.Generator().manual_seed(0)
        poses = KinematicMatrixFisher(F.float()[None], BODY_PARENTS).sample(100, generator)[:, 0]
        noise = torch.randn(100, 10, generator=generator)
        betas = betas_mean.float() + noise * betas_std.float()
        orient = FRONTAL_GLOBAL_ORIENT.expand(100, 3, 3)
        return vertex_uncertainty(body(betas, poses, orient).vertices)

    # The prior the evidence updates: the network's, tempered by the prior weight.
    weight = config.prior_weight
    prior_u = uncertainty(scene["start"].F[0] * weight, torch.zeros(10),
                          torch.ones(10) / weight**0.5)  # fmt: skip
    full_u = uncertainty(full.conditioned.F, full.conditioned.shape_mean,
                         full.conditioned.shape_std)  # fmt: skip
    covered_u = uncertainty(covered.conditioned.F, covered.conditioned.shape_mean,
                            covered.conditioned.shape_std)  # fmt: skip
    assert full_u.mean() < 0.9 * prior_u.mean()  # all keypoints seen: surer than the prior
    masks = limb_vertex_masks(body)
    leg = masks["left_lower_leg"]
    assert covered_u[leg].mean() > hidden_ratio * full_u[leg].mean()  # the hidden shin spreads
    for limb in ("left_forearm", "right_forearm", "right_lower_leg"):
        change = (covered_u[masks[limb]].mean() / full_u[masks[limb]].mean() - 1).abs()
        assert change < 0.2, limb


def test_too_little_or_non_finite_input_falls_back_with_a_reason(body64, scene) -> None:
    few = condition_on_keypoints(body64, scene["start"], _evidence(scene, range(3, 17)))
    assert not few.succeeded and "only 3 keypoint(s)" in few.reason
    bad = scene["start"]
    bad = replace(bad, F=bad.F.clone())
    bad.F[0, 4, 0, 0] = math.nan
    broken = condition_on_keypoints(body64, bad, _evidence(scene))
    assert not broken.succeeded and "not finite" in broken.reason


def test_the_lowest_cost_start_wins(body64, scene) -> None:
    good = scene["start"]
    turned = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.0, 2.5], dtype=torch.float64))
    starts = BodyDistribution(
        good.F.expand(2, -1, -1, -1), good.shape_mean.expand(2, -1), good.shape_std.expand(2, -1),
        torch.stack((turned @ good.global_orient[0], good.global_orient[0])),
        good.camera.expand(2, -1),
    )  # fmt: skip
    fit = condition_on_keypoints(body64, starts, _evidence(scene))
    assert fit.start == 1 and fit.costs[1] < fit.costs[0]


def test_matrix_fisher_from_precision_has_that_mode_and_curvature() -> None:
    generator = torch.Generator().manual_seed(0)
    mode = roma.rotvec_to_rotmat(torch.randn(5, 3, generator=generator, dtype=torch.float64))
    root = torch.randn(5, 3, 3, generator=generator, dtype=torch.float64)
    precision = root @ root.transpose(-1, -2) * 50 + torch.eye(3, dtype=torch.float64)
    F = matrix_fisher_from_precision(mode, precision)
    torch.testing.assert_close(MatrixFisher(F).mode, mode, rtol=0, atol=1e-5)
    torch.testing.assert_close(matrix_fisher_precision(F, mode), precision)
    # and the density's second derivative along a direction is that curvature
    direction = torch.tensor([0.3, -0.5, 0.8], dtype=torch.float64)
    step = 1e-4
    values = [
        (F * (mode @ roma.rotvec_to_rotmat(t * direction))).sum((-1, -2)) for t in (-step, 0, step)
    ]
    second = (values[0] - 2 * values[1] + values[2]) / step**2
    torch.testing.assert_close(-second, direction @ precision @ direction, rtol=1e-4, atol=1e-4)


def test_marginal_precisions_count_shared_evidence_once() -> None:
    # Two joints, one observation of their sum: each alone is unconstrained by it.
    precision = torch.tensor([[2.0, 1.0], [1.0, 2.0]], dtype=torch.float64)
    marginal = marginal_precisions(precision, 2, block_size=1)
    torch.testing.assert_close(marginal.flatten(), torch.full((2,), 1.5, dtype=torch.float64))
    block_diagonal = torch.block_diag(torch.eye(3) * 4, torch.eye(3) * 9).double()
    torch.testing.assert_close(
        marginal_precisions(block_diagonal, 2),
        torch.stack((torch.eye(3) * 4, torch.eye(3) * 9)).double(),
    )


def test_upright_view_maps_the_networks_answer_back_exactly() -> None:
    keypoints = np.stack([np.linspace(30, 100, 17), np.linspace(20, 110, 17)], 1)
    observed = np.ones(17, dtype=bool)
    tilt = torso_tilt(keypoints, observed)
    assert tilt is not None and abs(tilt) > math.radians(10)
    view = UprightView.from_tilt(tilt, keypoints, SIZE)
    upright = view.points(keypoints)
    assert abs(torso_tilt(upright, observed)) < 1e-9  # the copy shows the torso upright
    generator = torch.Generator().manual_seed(1)
    orient_copy = roma.random_rotmat(generator=generator).double()
    camera_copy = torch.tensor([1.1, 0.05, -0.1], dtype=torch.float64)
    points = torch.randn(9, 3, generator=generator, dtype=torch.float64)
    ndc_copy = camera_copy[0] * ((points @ orient_copy.T)[:, :2] + camera_copy[1:])
    orient, camera = view.to_crop_frame(orient_copy, camera_copy)
    ndc = camera[0] * ((points @ orient.T)[:, :2] + camera[1:])
    pixels_copy = view.points(ndc_to_pixels(ndc, SIZE).numpy())
    np.testing.assert_allclose(pixels_copy, ndc_to_pixels(ndc_copy, SIZE).numpy(), atol=1e-9)


def test_all_keypoints_seen_shrink_the_samples_2d_spread(body64, scene) -> None:
    config = EvidenceConfig()
    fit = condition_on_keypoints(body64, scene["start"], _evidence(scene), config)

    def spread_px(F: torch.Tensor, camera: torch.Tensor, orient: torch.Tensor) -> float:
        generator = torch.Generator().manual_seed(0)
        poses = KinematicMatrixFisher(F[None], BODY_PARENTS).sample(50, generator)[:, 0]
        betas = torch.zeros(50, 10, dtype=torch.float64)
        keypoints, joints = body64.posed_keypoints(betas, poses, orient.expand(50, 3, 3))
        relative = keypoints - joints[:, :1]
        pixels = ndc_to_pixels(camera[0] * (relative[..., :2] + camera[1:]), SIZE)
        return float((pixels - pixels.mean(0)).norm(dim=-1).mean())

    prior = scene["start"]
    before = spread_px(prior.F[0] * config.prior_weight, prior.camera[0], prior.global_orient[0])
    c = fit.conditioned
    after = spread_px(c.F, c.camera, c.global_orient)
    assert after < 0.7 * before

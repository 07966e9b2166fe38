"""Tests for hkpd.evaluation.evaluate_prediction on predictions built from the ground truth."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch
from test_network_helpers import make_training_batch

from hkpd.body import BodyModel
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.evaluation import EvaluationTargets, evaluate_prediction
from hkpd.training.losses import pelvis_relative_body


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


@pytest.fixture(scope="module")
def case(body):
    batch = make_training_batch(body, 3, 32, seed=7)
    camera = torch.tensor([[1.1, 0.0, 0.1]]).expand(3, 3)
    keypoints, _ = pelvis_relative_body(body, batch.betas, batch.body_pose, batch.global_orient)
    pixels = ndc_to_pixels(weak_perspective_project(keypoints, camera))
    targets = EvaluationTargets(batch.joints3d, batch.betas, pixels, batch.visible)
    return batch, camera, targets


def prediction(batch, camera, concentration: float, shape_std: float) -> BodyDistribution:
    return BodyDistribution(
        F=concentration * batch.body_pose,
        shape_mean=batch.betas,
        shape_std=torch.full_like(batch.betas, shape_std),
        global_orient=batch.global_orient,
        camera=camera,
    )


def test_perfect_mode_gives_zero_errors(body, case):
    batch, camera, targets = case
    output = prediction(batch, camera, 1e4, 1e-4)
    generator = torch.Generator().manual_seed(0)
    metrics = evaluate_prediction(output, body, targets, num_samples=2, generator=generator)
    for name in ("mpjpe", "mpjpe_sc", "mpjpe_pa", "pve_t_sc"):
        assert metrics[name].abs().max() < 1e-4, name
    assert metrics["joint_error_2d_mode"].max() < 1e-3
    # px; very concentrated samples (over 200 seeds the worst image was 1.2 px)
    assert metrics["joint_error_2d_samples"].max() < 1.5
    assert metrics["diversity_visible"].max() < 0.02  # metres; angle spread ~ 0.01 rad per joint
    assert set(metrics) >= {"mpjpe_min_of_1", "mpjpe_pa_min_of_1", "pve_t_sc_min_of_1"}
    assert "mpjpe_min_of_5" not in metrics  # only 2 samples


def test_broad_distributions_are_diverse_and_min_of_n_decreases(body, case):
    batch, camera, targets = case
    output = prediction(batch, camera, 2.0, 0.5)
    generator = torch.Generator().manual_seed(0)
    metrics = evaluate_prediction(output, body, targets, num_samples=5, generator=generator)
    assert metrics["diversity_visible"].min() > 0.05
    for name in ("mpjpe", "mpjpe_pa", "pve_t_sc"):
        assert (metrics[f"{name}_min_of_5"] <= metrics[f"{name}_min_of_1"]).all()
        assert (metrics[f"{name}_min_of_5"] < metrics[f"{name}_min_of_1"]).any()
    assert (metrics["joint_error_2d_samples"] > metrics["joint_error_2d_mode"]).all()
    # The mode sits on the targets, so the samples' spread about it is their error
    # (up to the mode's own error, by the triangle inequality), and it is not small.
    spread, error = metrics["joint_spread_2d_samples"], metrics["joint_error_2d_samples"]
    assert (spread - error).abs().max() <= metrics["joint_error_2d_mode"].max() + 1e-4
    assert spread.min() > 3.0  # px


def test_missing_targets_skip_their_metrics(body, case):
    batch, camera, targets = case
    output = prediction(batch, camera, 50.0, 0.1)
    only_2d = EvaluationTargets(keypoints2d=targets.keypoints2d, visible=targets.visible)
    metrics = evaluate_prediction(output, body, only_2d, num_samples=0)
    assert set(metrics) == {"joint_error_2d_mode"}
    assert not any(math.isnan(v) for v in metrics["joint_error_2d_mode"].tolist())
    with pytest.raises(ValueError, match="visible"):
        evaluate_prediction(output, body, EvaluationTargets(keypoints2d=targets.keypoints2d))


def test_pose_coverage_needs_the_true_pose_and_is_full_at_a_sharp_correct_mode(body, case):
    batch, camera, targets = case
    with_pose = replace(targets, body_pose=batch.body_pose)
    sharp = evaluate_prediction(prediction(batch, camera, 1e4, 1e-4), body, with_pose, 8)
    assert sharp["pose_coverage_50"].min() > 0.9  # truth at the mode: more probable than samples
    assert "pose_coverage_90" in sharp
    assert "pose_coverage_50" not in evaluate_prediction(
        prediction(batch, camera, 1e4, 1e-4), body, targets, 8
    )


def test_synthetic_evaluation_reports_2d_metrics_at_a_256_crop(body, case):
    from hkpd.evaluation.synthetic import evaluate_batches

    batch, camera, _ = case
    size = batch.proxy.shape[-1]
    output = prediction(batch, camera, 5.0, 0.3)

    class FixedNetwork(torch.nn.Module):
        def forward(self, proxy: torch.Tensor) -> BodyDistribution:
            return output

    reported = evaluate_batches(FixedNetwork(), [batch], body, num_samples=4, seed=3)
    targets = EvaluationTargets(
        batch.joints3d, batch.betas, batch.keypoints2d, batch.visible, batch.body_pose
    )
    direct = evaluate_prediction(output, body, targets, 4, size, torch.Generator().manual_seed(3))
    for name in ("joint_error_2d_mode", "joint_error_2d_samples", "joint_spread_2d_samples"):
        assert reported[name] == pytest.approx(float(direct[name].mean()) * 256 / size, rel=1e-5)
    assert reported["joint_spread_2d_samples"] > 1.0  # px: broad samples do spread
    assert reported["mpjpe"] == pytest.approx(float(direct["mpjpe"].mean()) * 1000, rel=1e-5)

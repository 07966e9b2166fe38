"""Tests for hkpd.training.losses and hkpd.training.schedule."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch
from test_network_helpers import make_training_batch, random_rotations

from hkpd.body import BodyModel
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.distributions import BodyDistribution
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.training.losses import (
    compute_losses,
    global_rotation_loss,
    joints3d_loss,
    keypoint_reprojection_loss,
    pelvis_relative_body,
    pose_nll,
    shape_nll,
)
from hkpd.training.schedule import (
    LOSS_TERMS,
    LossSchedule,
    LossStage,
    LossWeights,
    paper_schedule,
    paper_schedule_for,
)

STAGE_ONE_AND_3D = LossWeights(joints2d_samples=0.0)


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


@pytest.fixture(scope="module")
def batch(body):
    """A batch whose 2D targets are the weak-perspective projection of the GT bodies."""
    batch = make_training_batch(body, 4, 32, seed=5)
    keypoints, _ = pelvis_relative_body(body, batch.betas, batch.body_pose, batch.global_orient)
    camera = torch.tensor([[0.9, 0.02, -0.05]]).expand(4, 3)
    size = batch.proxy.shape[-1]
    batch.keypoints2d = ndc_to_pixels(weak_perspective_project(keypoints, camera), size)
    batch.camera = camera  # for the tests only
    return batch


def ground_truth_output(batch, concentration: float = 20.0) -> BodyDistribution:
    return BodyDistribution(
        F=concentration * batch.body_pose.clone(),
        shape_mean=batch.betas.clone(),
        shape_std=torch.full_like(batch.betas, 0.3),
        global_orient=batch.global_orient.clone(),
        camera=batch.camera.clone(),
    )


def perturbed(output: BodyDistribution, amount: float) -> BodyDistribution:
    generator = torch.Generator().manual_seed(9)
    twist = random_rotations(output.F.shape[:2], amount, generator)
    return BodyDistribution(
        F=output.F @ twist,
        shape_mean=output.shape_mean
        + amount * torch.randn(output.shape_mean.shape, generator=generator),
        shape_std=output.shape_std,
        global_orient=output.global_orient
        @ random_rotations((output.F.shape[0],), amount, generator),
        camera=output.camera + torch.tensor([amount * 0.2, amount * 0.1, 0.0]),
    )


def test_terms_are_finite_and_minimal_at_ground_truth(body, batch):
    truth = ground_truth_output(batch)
    weights = LossWeights(shape_tpose_vertices=1000.0)
    at_truth = compute_losses(truth, batch, body, weights, num_samples=2)
    assert set(at_truth) == {*LOSS_TERMS, "total"}
    assert all(torch.isfinite(v) for v in at_truth.values())
    assert at_truth["joints2d_mode"] < 1e-9 and at_truth["joints3d_mode"] < 1e-9
    assert at_truth["shape_tpose_vertices"] < 1e-12
    assert at_truth["global_rotation"] < 1e-9
    previous = None
    for amount in (0.1, 0.3):
        off = compute_losses(perturbed(truth, amount), batch, body, weights, num_samples=2)
        grown = ("shape_nll", "pose_nll", "global_rotation", "joints2d_mode", "joints3d_mode",
                 "shape_tpose_vertices")  # fmt: skip
        for name in grown:
            assert off[name] > at_truth[name], name
            if previous is not None:
                assert off[name] > previous[name], f"{name} does not grow with the error"
        previous = off


def test_inactive_terms_are_skipped(body, batch):
    weights = LossWeights(joints2d_samples=0.0, joints3d_mode=0.0, shape_nll=0.0)
    terms = compute_losses(ground_truth_output(batch), batch, body, weights)
    assert set(terms) == {"pose_nll", "global_rotation", "joints2d_mode", "total"}
    expected = (
        1.0 * terms["pose_nll"] + 100.0 * terms["global_rotation"] + 1000.0 * terms["joints2d_mode"]
    )
    torch.testing.assert_close(terms["total"], expected)


def test_nll_values_match_their_definitions():
    R = random_rotations((2, 23), 0.3, torch.Generator().manual_seed(3))
    assert pose_nll(torch.zeros(2, 23, 3, 3), R).item() == pytest.approx(0.0, abs=1e-6)
    # Concentrating on the right rotations lowers the NLL, on the wrong ones raises it.
    assert pose_nll(5.0 * R, R) < 0.0 < pose_nll(-5.0 * R, R)
    mean, std, betas = torch.zeros(1, 10), torch.ones(1, 10), torch.zeros(1, 10)
    expected = 10 * 0.5 * torch.log(torch.tensor(2 * torch.pi))
    torch.testing.assert_close(shape_nll(mean, std, betas), expected)
    eye = torch.eye(3).expand(1, 3, 3)
    flip = torch.diag(torch.tensor([1.0, -1.0, -1.0])).expand(1, 3, 3)
    assert global_rotation_loss(flip, eye).item() == pytest.approx(8.0)


def test_keypoint_loss_respects_visibility():
    target = torch.zeros(2, 17, 2)
    predicted = target.clone()
    predicted[:, 5] = 1.0  # wrong, but invisible
    visible = torch.ones(2, 17, dtype=torch.bool)
    visible[:, 5] = False
    assert keypoint_reprojection_loss(predicted, target, visible).item() == 0.0
    visible[0, 5] = True  # one of 33 visible keypoints is off by (1, 1)
    assert keypoint_reprojection_loss(predicted, target, visible).item() == pytest.approx(2 / 33)
    samples = torch.stack((predicted, target), dim=1)  # (B, S=2, 17, 2)
    assert keypoint_reprojection_loss(samples, target, visible).item() == pytest.approx(1 / 33)
    nothing = torch.zeros(2, 17, dtype=torch.bool)
    assert keypoint_reprojection_loss(predicted, target, nothing).item() == 0.0


def test_joints3d_loss_is_translation_invariant():
    joints = torch.randn(2, 24, 3)
    assert joints3d_loss(joints + 5.0, joints).item() == pytest.approx(0.0, abs=1e-10)
    moved = joints.clone()
    moved[:, 3] += torch.tensor([0.0, 0.24, 0.0])
    assert joints3d_loss(moved, joints).item() == pytest.approx(0.24**2 / 24)


def test_samples_loss_has_gradient_with_respect_to_F(body, batch):
    truth = ground_truth_output(batch, concentration=5.0)
    F = truth.F.clone().requires_grad_(True)
    std = truth.shape_std.clone().requires_grad_(True)
    output = replace(truth, F=F, shape_std=std)
    weights = LossWeights(0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    generator = torch.Generator().manual_seed(0)
    terms = compute_losses(output, batch, body, weights, num_samples=3, generator=generator)
    assert set(terms) == {"joints2d_samples", "total"}
    assert terms["joints2d_samples"] > 0
    terms["total"].backward()
    assert torch.isfinite(F.grad).all() and F.grad.abs().sum() > 0
    assert torch.isfinite(std.grad).all() and std.grad.abs().sum() > 0


def test_sample_loss_shrinks_with_concentration(body, batch):
    weights = LossWeights(0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    values = []
    for concentration in (2.0, 50.0):
        output = ground_truth_output(batch, concentration)
        output = replace(output, shape_std=torch.full_like(output.shape_std, 0.01))
        generator = torch.Generator().manual_seed(1)
        terms = compute_losses(output, batch, body, weights, num_samples=8, generator=generator)
        values.append(terms["joints2d_samples"].item())
    assert values[1] < 0.2 * values[0]


def test_batch_size_mismatch_is_rejected(body, batch):
    truth = ground_truth_output(batch)
    smaller = truth.rows(slice(0, 2))
    with pytest.raises(ValueError, match="batch size"):
        compute_losses(smaller, batch, body, LossWeights())


def test_paper_schedule_stages():
    schedule = paper_schedule(100, 200)
    first, second, third = (schedule.weights_at(s) for s in (0, 150, 250))
    assert first.active() == ("shape_nll", "pose_nll", "global_rotation", "joints2d_mode")
    assert second.active() == (*first.active(), "joints2d_samples")
    assert third.active() == tuple(t for t in LOSS_TERMS if t != "shape_tpose_vertices")  # off
    assert schedule.weights_at(99) == first and schedule.weights_at(100) == second
    assert schedule.stage_index(199) == 1 and schedule.stage_index(200) == 2
    assert LossSchedule.from_dict(schedule.to_dict()) == schedule
    assert paper_schedule_for(300) == schedule.__class__(
        tuple(
            replace(stage, start_step=start)
            for stage, start in zip(schedule.stages, (0, 100, 200), strict=True)
        )
    )
    with pytest.raises(ValueError, match="samples_start"):
        paper_schedule(200, 100)
    with pytest.raises(ValueError, match="increase strictly"):
        LossSchedule((LossStage(0, first), LossStage(0, second)))
    with pytest.raises(ValueError, match=">= 0"):
        LossWeights(pose_nll=-1.0)


@pytest.fixture
def single_thread():
    """Tiny tensors gain nothing from a second thread, and lose a lot on a busy machine."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_tiny_network_overfits_a_fixed_batch(body, single_thread):
    torch.manual_seed(0)
    batch = make_training_batch(body, 4, 32, seed=11)
    config = NetworkConfig(backbone_base_width=8, head_hidden=64, joint_hidden=(32,), image_size=32)
    network = DistributionNetwork(config)
    optimiser = torch.optim.Adam(network.parameters(), lr=3e-3)
    history = []
    for _ in range(12):
        terms = compute_losses(network(batch.proxy), batch, body, STAGE_ONE_AND_3D)
        optimiser.zero_grad()
        terms["total"].backward()
        optimiser.step()
        history.append({name: value.item() for name, value in terms.items()})
    first, last = history[0], history[-1]
    assert all(torch.isfinite(torch.tensor(list(h.values()))).all() for h in history)
    assert last["total"] < first["total"] - 0.5 * abs(first["total"]), history
    for name in ("pose_nll", "joints2d_mode", "joints3d_mode"):
        assert last[name] < first[name], (name, history)
    # The samples loss runs on the trained network too.
    terms = compute_losses(network(batch.proxy), batch, body, LossWeights(), num_samples=2)
    assert torch.isfinite(terms["total"])


def test_losses_work_inside_autocast(body, batch):
    truth = ground_truth_output(batch)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        inside = compute_losses(truth, batch, body, STAGE_ONE_AND_3D)
    outside = compute_losses(truth, batch, body, STAGE_ONE_AND_3D)
    for name, value in outside.items():
        assert inside[name].dtype == torch.float32
        torch.testing.assert_close(inside[name], value)


def _shape_gradients(output: BodyDistribution, batch, body, shape_from_nll_only: bool) -> dict:
    """Gradient norm on the shape mean and std of each term, alone."""
    norms = {}
    for term in ("shape_nll", "joints2d_mode", "joints2d_samples", "joints3d_mode"):
        mean = output.shape_mean.clone().requires_grad_(True)
        std = output.shape_std.clone().requires_grad_(True)
        pose = output.F.clone().requires_grad_(True)  # keeps every total in the graph
        weights = LossWeights(**{name: float(name == term) for name in LOSS_TERMS})
        terms = compute_losses(
            replace(output, F=pose, shape_mean=mean, shape_std=std), batch, body, weights,
            num_samples=2, generator=torch.Generator().manual_seed(0),
            shape_from_nll_only=shape_from_nll_only,
        )  # fmt: skip
        gradients = torch.autograd.grad(terms["total"], (mean, std), allow_unused=True)
        norms[term] = sum(0.0 if g is None else float(g.norm()) for g in gradients)
    return norms


def test_shape_from_nll_only_leaves_the_shape_to_the_nll(body, batch):
    off = perturbed(ground_truth_output(batch), 0.3)
    coupled = _shape_gradients(off, batch, body, shape_from_nll_only=False)
    alone = _shape_gradients(off, batch, body, shape_from_nll_only=True)
    for term in ("joints2d_mode", "joints2d_samples", "joints3d_mode"):
        assert coupled[term] > 1e-4, (term, coupled)  # the joint terms do pull the shape ...
        assert alone[term] == 0.0, (term, alone)  # ... unless it is detached for them
    assert alone["shape_nll"] > 0.0
    assert alone["shape_nll"] == pytest.approx(coupled["shape_nll"])
    # The joint terms' values do not change, only where their gradients go.
    plain = compute_losses(off, batch, body, STAGE_ONE_AND_3D)
    detached = compute_losses(off, batch, body, STAGE_ONE_AND_3D, shape_from_nll_only=True)
    for name, value in plain.items():
        torch.testing.assert_close(detached[name], value)

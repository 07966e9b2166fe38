"""The posterior's research summaries (issue 51): mean uncertainty per body part, and the log
density of bodies under the pose matrix-Fisher and the shape Gaussian (Haar probability measure
on SO(3)^23 times Lebesgue on β)."""

from __future__ import annotations

import math

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.distributions import BodyDistribution
from hkpd.prediction.posterior_summaries import part_uncertainty, posterior_log_prob

JOINTS, BETAS = 23, 10


def distribution(concentration: float = 5.0, seed: int = 0) -> BodyDistribution:
    """One person's record with random per-joint parameters and shape Gaussian."""
    generator = torch.Generator().manual_seed(seed)
    return BodyDistribution(
        concentration * torch.randn(JOINTS, 3, 3, generator=generator),
        torch.randn(BETAS, generator=generator),
        0.2 + torch.rand(BETAS, generator=generator),
        torch.eye(3),
        torch.tensor([0.9, 0.0, 0.1]),
    )


def test_part_uncertainty_is_the_mean_of_each_parts_vertices() -> None:
    values = torch.tensor([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    labels = torch.tensor([0, 0, 1, 1, 1, 2])
    means = part_uncertainty(values, labels, ("head", "arm", "leg", "tail"))
    assert list(means) == ["head", "arm", "leg", "tail"]
    assert means["head"] == 1.5 and means["arm"] == 4.0 and means["leg"] == 6.0
    assert math.isnan(means["tail"])  # no vertex of it


def test_part_uncertainty_on_the_body_models_parts() -> None:
    body = BodyModel()
    values = body.part_labels.double() * 0.01 + 0.005  # metres, by part
    means = part_uncertainty(values.float(), body.part_labels, body.part_names)
    assert list(means) == list(body.part_names) and len(means) == 24
    for index, name in enumerate(body.part_names):
        assert means[name] == pytest.approx(index * 0.01 + 0.005, abs=1e-7)


@pytest.mark.parametrize(
    "values, labels, match",
    [
        (torch.ones(3), torch.tensor([0, 1]), r"\(V,\)"),
        (torch.ones(2, 3), torch.zeros(2, 3, dtype=torch.long), r"\(V,\)"),
        (torch.ones(2), torch.tensor([0.0, 1.0]), "integer"),
        (torch.ones(2), torch.tensor([0, 4]), "index the 4 part_names"),
        (torch.ones(2), torch.tensor([-1, 0]), "index the 4 part_names"),
    ],
)
def test_part_uncertainty_refuses_what_does_not_fit(values, labels, match) -> None:
    with pytest.raises(ValueError, match=match):
        part_uncertainty(values, labels, ("a", "b", "c", "d"))
    with pytest.raises(ValueError, match="distinct"):
        part_uncertainty(torch.ones(2), torch.tensor([0, 1]), ("a", "a"))


def test_log_prob_is_the_pose_and_shape_distributions_log_probs() -> None:
    record = distribution()
    generator = torch.Generator().manual_seed(1)
    poses = record.pose_distribution().sample((40,), generator=generator)
    betas = record.shape_distribution().sample((40,))
    found = posterior_log_prob(record, poses, betas)
    assert found.shape == (40,) and found.dtype == torch.float64
    expected = record.pose_distribution().log_prob(poses) + record.shape_distribution().log_prob(
        betas
    )
    torch.testing.assert_close(found, expected.double(), rtol=1e-5, atol=1e-4)
    far = torch.eye(3).expand(40, JOINTS, 3, 3)  # the rest pose: far less likely here
    assert (posterior_log_prob(record, far, betas) < found.min()).all()


def test_units_uniform_pose_and_standard_normal_shape() -> None:
    """F = 0 is the uniform distribution on SO(3)^23: log density 0 w.r.t. the Haar probability
    measure for any pose; the shape part is the Gaussian's density in β."""
    record = distribution()
    uniform = BodyDistribution(torch.zeros(JOINTS, 3, 3), *record.tensors()[1:])
    poses = roma.random_rotmat(5 * JOINTS, dtype=torch.float64).reshape(5, JOINTS, 3, 3)
    betas = torch.randn(5, BETAS, generator=torch.Generator().manual_seed(2))
    mean, std = record.shape_mean.double(), record.shape_std.double()
    gaussian = (
        -0.5 * (((betas.double() - mean) / std) ** 2).sum(-1)
        - std.log().sum()
        - 0.5 * BETAS * math.log(2 * math.pi)
    )
    torch.testing.assert_close(posterior_log_prob(uniform, poses, betas), gaussian)


def test_the_pose_density_integrates_to_one_over_haar_rotations() -> None:
    """E over uniform (Haar) rotations of exp(log p) is 1: the density is w.r.t. the Haar
    probability measure. One concentrated joint (the others uniform), Monte Carlo over 20,000
    uniform poses; at the shape mean with std 1 the shape part is -5 log(2 pi)."""
    torch.manual_seed(3)
    F = torch.zeros(JOINTS, 3, 3)
    F[4] = roma.random_rotmat(dtype=torch.float64).float() @ torch.diag(
        torch.tensor([3.0, 2.0, 0.5])
    )
    record = BodyDistribution(F, torch.zeros(BETAS), torch.ones(BETAS), torch.eye(3), torch.ones(3))
    count = 20_000
    poses = torch.eye(3, dtype=torch.float64).repeat(count, JOINTS, 1, 1)
    poses[:, 4] = roma.random_rotmat(count, dtype=torch.float64)
    log_p = posterior_log_prob(record, poses, torch.zeros(count, BETAS))
    pose_density = (log_p + 0.5 * BETAS * math.log(2 * math.pi)).exp()
    standard_error = float(pose_density.std()) / math.sqrt(count)
    assert abs(float(pose_density.mean()) - 1.0) < 4 * standard_error + 1e-3


def test_gradients_reach_the_distribution() -> None:
    record = distribution()
    F = record.F.clone().requires_grad_(True)
    mean = record.shape_mean.clone().requires_grad_(True)
    with_grad = BodyDistribution(F, mean, *record.tensors()[2:])
    poses = record.pose_distribution().sample((3,))
    posterior_log_prob(with_grad, poses, torch.zeros(3, BETAS)).sum().backward()
    assert F.grad is not None and torch.isfinite(F.grad).all() and F.grad.abs().sum() > 0
    assert mean.grad is not None and mean.grad.abs().sum() > 0


def test_log_prob_refuses_what_does_not_fit() -> None:
    record = distribution()
    poses = torch.eye(3).repeat(2, JOINTS, 1, 1)
    betas = torch.zeros(2, BETAS)
    batched = record.map(lambda tensor: tensor.unsqueeze(0))
    cases = [
        (batched, poses, betas, "one person's distribution"),
        (record, poses[:, :22], betas, "body_pose must be"),
        (record, poses, betas[:, :9], "betas must be"),
        (record, poses, torch.zeros(3, BETAS), "same N"),
        (record, poses * 1.1, betas, "rotation matrices"),
        (record, -poses, betas, "rotation matrices"),  # det -1
        (record, poses, betas.clone().fill_(math.nan), "finite"),
    ]
    for one, pose, beta, match in cases:
        with pytest.raises(ValueError, match=match):
            posterior_log_prob(one, pose, beta)

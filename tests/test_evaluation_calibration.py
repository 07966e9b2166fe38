"""Tests for hkpd.evaluation.calibration: coverage of true rotations by the predicted regions."""

from __future__ import annotations

import pytest
import roma
import torch

from hkpd.distributions.matrix_fisher import MatrixFisher
from hkpd.evaluation.calibration import rotation_coverage, truth_rank

EXAMPLES, JOINTS, SAMPLES = 16, 23, 200


@pytest.fixture(scope="module")
def parameters() -> torch.Tensor:
    """``(B, J, 3, 3)`` matrix-Fisher parameters with concentrations 5 to 40."""
    torch.manual_seed(3)
    scale = torch.linspace(5.0, 40.0, JOINTS).view(1, JOINTS, 1, 1)
    return scale * roma.random_rotmat((EXAMPLES, JOINTS))


def draw(F: torch.Tensor, count: int, seed: int) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return MatrixFisher(F).sample((count,), generator=generator)


def test_truth_drawn_from_the_distribution_is_covered_at_the_nominal_rate(parameters):
    samples = draw(parameters, SAMPLES, 0)
    truth = draw(parameters, 1, 1)[0]
    coverage = rotation_coverage(parameters, samples, truth, levels=(0.5, 0.9))
    assert abs(float(coverage[0.5].mean()) - 0.5) < 0.06
    assert abs(float(coverage[0.9].mean()) - 0.9) < 0.05


def test_over_confident_distribution_covers_too_little(parameters):
    samples = draw(parameters, SAMPLES, 0)
    truth = draw(parameters / 10, 1, 1)[0]  # the truth varies far more than the prediction says
    coverage = rotation_coverage(parameters, samples, truth)
    assert float(coverage[0.9].mean()) < 0.5
    assert float(truth_rank(parameters, samples, truth).mean()) > 0.8


def test_truth_at_the_mode_is_always_covered(parameters):
    samples = draw(parameters, SAMPLES, 0)
    mode = MatrixFisher(parameters).mode
    ranks = truth_rank(parameters, samples, mode)
    assert ranks.shape == (EXAMPLES, JOINTS)
    assert float(ranks.max()) == 0.0
    assert float(rotation_coverage(parameters, samples, mode)[0.5].min()) == 1.0


def test_mismatched_shapes_are_refused(parameters):
    samples = draw(parameters, 4, 0)
    with pytest.raises(ValueError, match="samples"):
        truth_rank(parameters, samples[:, :3], parameters)


def test_point_ranks_are_calibrated_when_the_truth_is_drawn_like_the_samples() -> None:
    from hkpd.evaluation.calibration import calibrated_coverage, point_truth_rank

    torch.manual_seed(3)
    mode = torch.randn(4000, 17, 2) * 50
    spread = torch.rand(4000, 17, 1) * 10 + 1
    samples = mode + spread * torch.randn(25, 4000, 17, 2)
    truth = mode + spread * torch.randn(4000, 17, 2)
    ranks = point_truth_rank(mode, samples, truth)
    assert ranks.shape == (4000, 17)
    for level in (0.5, 0.9):
        share = (ranks < level).double().mean().item()
        assert abs(share - calibrated_coverage(level, 25)) < 0.01
    # samples twice too narrow: the truth falls outside the 90 % disc far more often
    narrow = point_truth_rank(mode, mode + 0.5 * (samples - mode), truth)
    assert (narrow < 0.9).double().mean().item() < 0.6
    with pytest.raises(ValueError, match="expected mode"):
        point_truth_rank(mode, samples[:, :, :3], truth)


def test_calibrated_coverage_counts_the_finite_samples() -> None:
    from hkpd.evaluation.calibration import calibrated_coverage

    assert calibrated_coverage(0.5, 25) == 0.5
    assert calibrated_coverage(0.9, 25) == pytest.approx(23 / 26)
    assert calibrated_coverage(0.5, 10) == pytest.approx(5 / 11)
    with pytest.raises(ValueError):
        calibrated_coverage(1.0, 25)

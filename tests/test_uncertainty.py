"""Per-vertex uncertainty from sampled meshes."""

from __future__ import annotations

import math

import pytest
import torch

from hkpd.uncertainty import vertex_uncertainty


def test_identical_samples_have_zero_uncertainty() -> None:
    mesh = torch.randn(50, 3, dtype=torch.float64)
    assert vertex_uncertainty(mesh.expand(100, 50, 3)).abs().max() < 1e-14
    assert torch.equal(vertex_uncertainty(mesh[None]), torch.zeros(50, dtype=torch.float64))


def test_samples_on_a_circle_spread_by_its_radius() -> None:
    # Vertex v's N samples lie evenly on a circle of radius r_v about a centre: the sample
    # mean is the centre, and every sample is r_v from it.
    count = 12
    angles = torch.arange(count, dtype=torch.float64) * 2 * math.pi / count
    radii = torch.tensor([0.0, 0.01, 0.5, 2.0], dtype=torch.float64)
    centre = torch.tensor([0.3, -1.0, 2.0], dtype=torch.float64)
    ring = torch.stack((angles.cos(), angles.sin(), torch.zeros_like(angles)), dim=-1)
    samples = centre + radii[None, :, None] * ring[:, None, :]  # (N, V, 3)
    assert torch.allclose(vertex_uncertainty(samples), radii, atol=1e-12)


def test_two_samples_spread_by_half_their_distance() -> None:
    first, second = torch.randn(7, 3), torch.randn(7, 3)
    expected = (first - second).norm(dim=-1) / 2
    result = vertex_uncertainty(torch.stack((first, second)))
    assert torch.allclose(result, expected, atol=1e-6)


def test_leading_batch_dimensions() -> None:
    samples = torch.randn(2, 4, 100, 30, 3)
    result = vertex_uncertainty(samples)
    assert result.shape == (2, 4, 30)
    assert torch.allclose(result[1, 2], vertex_uncertainty(samples[1, 2]))
    assert (vertex_uncertainty(samples * 3) - 3 * result).abs().max() < 1e-5


def test_invalid_shapes_are_rejected() -> None:
    with pytest.raises(ValueError, match=r"\(\.\.\., N, V, 3\)"):
        vertex_uncertainty(torch.zeros(10, 3))
    with pytest.raises(ValueError, match=r"\(\.\.\., N, V, 3\)"):
        vertex_uncertainty(torch.zeros(10, 5, 2))
    with pytest.raises(ValueError, match="at least one sample"):
        vertex_uncertainty(torch.zeros(0, 5, 3))

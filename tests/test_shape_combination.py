"""The combination of several photos' shape Gaussians (hkpd.prediction.shape_combination)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
import torch

from hkpd.body import BodyModel
from hkpd.prediction.shape_combination import (
    CombinedShape,
    combine_gaussians,
    combine_shapes,
    mean_of_gaussians,
    product_of_gaussians,
    shape_vertex_uncertainty,
    tpose_meshes,
)


@dataclass
class Shape:
    shape_mean: torch.Tensor
    shape_std: torch.Tensor


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return BodyModel()


def _random_gaussians(count: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    generator = torch.Generator().manual_seed(seed)
    means = torch.randn(count, 10, generator=generator, dtype=torch.float64)
    stds = 0.1 + torch.rand(count, 10, generator=generator, dtype=torch.float64)
    return means, stds


def test_two_gaussians_match_the_closed_form():
    means = torch.tensor([[0.0, 1.0], [2.0, -1.0]], dtype=torch.float64)
    stds = torch.tensor([[1.0, 0.5], [2.0, 0.5]], dtype=torch.float64)
    mean, std = product_of_gaussians(means, stds)
    # Coefficient 0: precisions 1 and 1/4 -> variance 0.8, mean (0*1 + 2/4) * 0.8 = 0.4.
    torch.testing.assert_close(mean, torch.tensor([0.4, 0.0], dtype=torch.float64))
    torch.testing.assert_close(std, torch.tensor([0.8**0.5, 0.5 / 2**0.5], dtype=torch.float64))


def test_product_matches_a_brute_force_product_of_densities():
    """Multiply the N densities on a fine grid per coefficient and read off mean and std."""
    means, stds = _random_gaussians(4, seed=3)
    mean, std = product_of_gaussians(means, stds)
    grid = torch.linspace(-8, 8, 200_001, dtype=torch.float64)
    for k in range(means.shape[1]):
        log_density = sum(
            torch.distributions.Normal(means[i, k], stds[i, k]).log_prob(grid)
            for i in range(means.shape[0])
        )
        weights = torch.softmax(log_density, 0)
        grid_mean = (weights * grid).sum()
        grid_std = (weights * (grid - grid_mean) ** 2).sum().sqrt()
        assert float(mean[k]) == pytest.approx(float(grid_mean), abs=1e-6)
        assert float(std[k]) == pytest.approx(float(grid_std), rel=1e-4)


def test_an_identical_photo_halves_the_variance_and_keeps_the_mean():
    means, stds = _random_gaussians(1)
    mean, std = product_of_gaussians(means.repeat(2, 1), stds.repeat(2, 1))
    torch.testing.assert_close(mean, means[0])
    torch.testing.assert_close(std**2, stds[0] ** 2 / 2)
    # N identical photos: std / sqrt(N).
    _, std5 = product_of_gaussians(means.repeat(5, 1), stds.repeat(5, 1))
    torch.testing.assert_close(std5, stds[0] / 5**0.5)


def test_a_very_uncertain_photo_barely_moves_the_result():
    sure_mean, sure_std = torch.zeros(1, 10), torch.full((1, 10), 0.2)
    unsure_mean, unsure_std = torch.full((1, 10), 3.0), torch.full((1, 10), 50.0)
    mean, std = product_of_gaussians(
        torch.cat([sure_mean, unsure_mean]), torch.cat([sure_std, unsure_std])
    )
    assert float(mean.abs().max()) < 3.0 * 0.2**2 / 50.0**2 * 1.01  # about 5e-5
    torch.testing.assert_close(std, sure_std[0], atol=1e-5, rtol=1e-5)
    # The plain mean is pulled halfway: exactly what the product avoids.
    baseline, baseline_std = mean_of_gaussians(
        torch.cat([sure_mean, unsure_mean]), torch.cat([sure_std, unsure_std])
    )
    torch.testing.assert_close(baseline, torch.full((10,), 1.5))
    torch.testing.assert_close(baseline_std, torch.full((10,), ((0.04 + 2500) / 2) ** 0.5))


def test_one_photo_is_returned_unchanged_and_batch_dims_are_kept():
    means, stds = _random_gaussians(1)
    for method in ("product", "mean"):
        mean, std = combine_gaussians(means, stds, method)
        torch.testing.assert_close(mean, means[0])
        torch.testing.assert_close(std, stds[0])
    batched = torch.randn(3, 7, 10), 0.5 + torch.rand(3, 7, 10)
    mean, std = product_of_gaussians(*batched)
    assert mean.shape == std.shape == (7, 10)
    torch.testing.assert_close(mean[4], product_of_gaussians(batched[0][:, 4], batched[1][:, 4])[0])


def test_errors_say_what_is_wrong():
    with pytest.raises(ValueError, match="at least one photo"):
        combine_shapes([], BodyModel())
    with pytest.raises(ValueError, match="at least one photo"):
        product_of_gaussians(torch.zeros(0, 10), torch.ones(0, 10))
    with pytest.raises(ValueError, match="photo 2 has 11 shape coefficients but photo 1 has 10"):
        shapes = [Shape(torch.zeros(10), torch.ones(10)), Shape(torch.zeros(11), torch.ones(11))]
        combine_shapes(shapes, BodyModel())
    stds = torch.ones(3, 10)
    stds[2, 4] = 0.0
    message = r"photo 3: shape std of coefficient 4 is 0.0; it must be finite and > 0"
    with pytest.raises(ValueError, match=message):
        product_of_gaussians(torch.zeros(3, 10), stds)
    stds[2, 4] = float("inf")
    with pytest.raises(ValueError, match="photo 3: shape std of coefficient 4 is inf"):
        mean_of_gaussians(torch.zeros(3, 10), stds)
    stds[2, 4] = -1.0
    with pytest.raises(ValueError, match="must be finite and > 0"):
        product_of_gaussians(torch.zeros(3, 10), stds)
    means = torch.zeros(2, 10)
    means[1, 0] = float("nan")
    with pytest.raises(ValueError, match="photo 2: shape mean of coefficient 0 is nan"):
        product_of_gaussians(means, torch.ones(2, 10))
    with pytest.raises(ValueError, match="method must be one of product, mean"):
        combine_gaussians(torch.zeros(1, 10), torch.ones(1, 10), "median")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="must both be \\(K,\\) vectors"):
        combine_shapes([Shape(torch.zeros(1, 10), torch.ones(1, 10))], BodyModel())
    with pytest.raises(ValueError, match="body model has 10"):
        combine_shapes([Shape(torch.zeros(8), torch.ones(8))], BodyModel())
    with pytest.raises(ValueError, match="integer >= 2"):
        shape_vertex_uncertainty(BodyModel(), torch.zeros(10), torch.ones(10), n=1)


def test_combined_shape_mesh_and_uncertainty(body):
    photos = [Shape(torch.full((10,), 0.5), torch.full((10,), 0.4)) for _ in range(4)]
    one = combine_shapes(photos[:1], body)
    four = combine_shapes(photos, body)
    assert isinstance(four, CombinedShape) and four.count == 4 and four.method == "product"
    torch.testing.assert_close(four.betas_std, torch.full((10,), 0.2))
    assert four.mean_std == pytest.approx(0.2)
    assert four.tpose_vertices.shape == (body.num_vertices, 3)
    assert four.vertex_uncertainty.shape == (body.num_vertices,)
    assert four.faces.shape[1] == 3
    # Same mean shape, so the same mesh; the mesh faces the camera (head up = negative y).
    torch.testing.assert_close(one.tpose_vertices, four.tpose_vertices)
    head = int(four.tpose_vertices[:, 1].argmin())
    assert float(four.tpose_vertices[head, 1]) < -0.4
    # Shape is linear in betas: halving the std halves the vertex spread (same noise).
    ratio = four.vertex_uncertainty / one.vertex_uncertainty
    torch.testing.assert_close(ratio, torch.full_like(ratio, 0.5), atol=1e-4, rtol=1e-4)
    assert float(one.vertex_uncertainty.mean()) > 0.005
    mean = combine_shapes(photos, body, method="mean")
    torch.testing.assert_close(mean.betas_std, torch.full((10,), 0.4))


def test_tpose_meshes_are_pelvis_relative_rest_bodies(body):
    betas = torch.randn(2, 10)
    meshes = tpose_meshes(body, betas)
    flipped = meshes * torch.tensor([1.0, -1.0, -1.0])  # back to the model's Y-up frame
    rest = body.tpose(betas) - body.rest_joints(betas)[:, :1]
    torch.testing.assert_close(flipped, rest)

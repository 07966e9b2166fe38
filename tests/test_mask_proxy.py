"""The ``"edges+mask"`` proxy (edges + a person-probability mask), the widening of an edge
network to it, and the per-vertex T-pose shape loss."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.body import BodyModel
from hkpd.network import DistributionNetwork, NetworkConfig
from hkpd.network.checkpoint import load_initial_weights, save_checkpoint
from hkpd.poses import ProceduralPosePrior
from hkpd.proxy import build_proxy_batch, image_planes_batch, proxy_channels
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator
from hkpd.training.losses import tpose_vertex_loss


def test_mask_plane_holds_probabilities_and_none_is_all_zero():
    images = np.zeros((2, 32, 32, 3), np.uint8)
    probability = np.zeros((2, 32, 32), np.float32)
    probability[0, 8:24, 10:20] = 0.5
    planes = image_planes_batch(images, "edges+mask", probability)
    assert planes.shape == (2, 2, 32, 32)
    assert int(planes[0, 1, 10, 12]) == 128 and int(planes[0, 1, 0, 0]) == 0
    assert int(image_planes_batch(images, "edges+mask", None)[:, 1].max()) == 0
    with pytest.raises(ValueError, match="person masks must be"):
        image_planes_batch(images, "edges+mask", probability[:, :16])
    proxy = build_proxy_batch(images, torch.zeros(2, 17, 2), torch.zeros(2, 17, dtype=bool),
                              image_proxy="edges+mask", silhouettes=probability)  # fmt: skip
    assert proxy.shape[1] == proxy_channels("edges+mask") == 19


def test_synthetic_mask_plane_follows_the_body_and_is_zero_where_occluded():
    config = SyntheticDataConfig(image_size=64, image_proxy="edges+mask",
                                 mask_missing_probability=0.0)  # fmt: skip
    rendered = SyntheticDataGenerator(ProceduralPosePrior(), config).generate(4, seed=3)
    mask = rendered.batch.proxy[:, 1]
    body = rendered.part_map >= 0
    inside = mask[body & ~rendered.occluded].mean()
    outside = mask[~body].mean()
    assert inside > 0.8 and outside < 0.1
    assert float(mask[rendered.occluded].abs().max()) == 0.0
    none = SyntheticDataConfig(image_size=64, image_proxy="edges+mask", mask_missing_probability=1)
    missing = SyntheticDataGenerator(ProceduralPosePrior(), none).generate(2, seed=3)
    assert float(missing.batch.proxy[:, 1].max()) == 0.0


def test_an_edge_network_widened_to_the_mask_proxy_predicts_what_it_did(tmp_path):
    torch.manual_seed(0)
    small = {"backbone_base_width": 8, "image_size": 64, "head_hidden": 32, "joint_hidden": (16,)}
    config = NetworkConfig(**small)
    edges = DistributionNetwork(config).eval()
    path = save_checkpoint(tmp_path / "edges.pt", edges, config.to_dict(), 0, {}, 0)
    masked = DistributionNetwork(NetworkConfig(**small, image_proxy="edges+mask",
                                               input_channels=19))  # fmt: skip
    load_initial_weights(masked, path, "cpu")
    masked.eval()
    proxy = torch.rand(2, 18, 64, 64)
    widened = torch.cat([proxy[:, :1], torch.rand(2, 1, 64, 64), proxy[:, 1:]], 1)
    with torch.no_grad():
        before, after = edges(proxy), masked(widened)
    assert torch.allclose(before.F, after.F, atol=1e-6)
    assert torch.allclose(before.shape_mean, after.shape_mean, atol=1e-6)


def test_tpose_vertex_loss_is_the_rest_vertices_squared_distance():
    body = BodyModel().double()
    betas = torch.randn(3, body.num_betas, dtype=torch.float64)
    mean = betas + 0.3 * torch.randn_like(betas)
    expected = (body.tpose(mean) - body.tpose(betas)).square().sum(-1).mean()
    assert torch.allclose(tpose_vertex_loss(body, mean, betas), expected)
    assert float(tpose_vertex_loss(body, betas, betas)) == 0.0

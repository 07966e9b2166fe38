"""The 2D losses read pixel coordinates at the batch's own crop size (a 128-px network must not
be trained against targets scaled for 256 px)."""

from __future__ import annotations

import torch

from hkpd.network import DistributionNetwork
from hkpd.network.config import NetworkConfig
from hkpd.poses import ProceduralPosePrior
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator
from hkpd.training.losses import compute_losses
from hkpd.training.schedule import LossWeights


def test_default_crop_size_is_the_batch_size() -> None:
    generator = SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=64))
    batch = generator.generate(2, seed=0).batch
    torch.manual_seed(0)
    network = DistributionNetwork(NetworkConfig(backbone_base_width=8, image_size=64))
    with torch.no_grad():
        output = network(batch.proxy)
    weights = LossWeights(shape_nll=0, pose_nll=0, global_rotation=0, joints2d_samples=0,
                          joints3d_mode=0)  # fmt: skip
    body = generator.body
    inferred = compute_losses(output, batch, body, weights)["joints2d_mode"]
    explicit = compute_losses(output, batch, body, weights, crop_size=64)["joints2d_mode"]
    wrong = compute_losses(output, batch, body, weights, crop_size=256)["joints2d_mode"]
    torch.testing.assert_close(inferred, explicit)
    assert not torch.allclose(inferred, wrong)

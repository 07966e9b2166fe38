"""One rank of the gradient check in tests/test_training_distributed.py (run under torchrun).

Every rank builds the same tiny network, takes its own batch (:func:`rank_batch`), runs the
training loss through :func:`hkpd.training.distributed.wrap_for_training` and ``backward``;
rank 0 saves the gradients DistributedDataParallel left, once with batch normalisation on
running statistics (``eval``) and once on batch statistics (``train``)::

    python -m torch.distributed.run --standalone --nproc-per-node 2 \\
        tests/ddp_gradient_worker.py GRADIENTS.pt
"""

from __future__ import annotations

import sys
from dataclasses import fields

import torch

from hkpd.body import BodyModel
from hkpd.network import DistributionNetwork
from hkpd.poses import pose_source
from hkpd.synthesis.batch import TrainingBatch
from hkpd.synthesis.generator import SyntheticDataGenerator
from hkpd.training.config import TrainConfig
from hkpd.training.distributed import (
    detect_launch,
    end_process_group,
    start_process_group,
    wrap_for_training,
)
from hkpd.training.loop import build_schedule
from hkpd.training.losses import compute_losses

CONFIG = TrainConfig(
    batch_size=4, image_size=64, backbone_base_width=8, samples_loss_from=-1,
    joints3d_loss_from=0, num_samples=2, mode_loss_weight=0.0,
)  # fmt: skip
"""The losses that are means over the examples (the NLLs, the global rotation, 3D joints).
The 2D keypoint losses divide by the visible keypoints of the batch at hand, so averaged over
ranks they weigh a rank's keypoints by that rank's count, not the global one: they are left
out here (docs/gpu_training.md)."""

MODES = ("eval", "train")


def tiny_network() -> DistributionNetwork:
    torch.manual_seed(3)
    return DistributionNetwork(CONFIG.network_config())


def rank_batch(rank: int) -> TrainingBatch:
    """Rank ``rank``'s batch of ``CONFIG.batch_size`` examples."""
    poses = pose_source(None, "train", CONFIG.pose_mix())
    generator = SyntheticDataGenerator(poses, CONFIG.data_config(), torch.device("cpu"))
    return generator.generate(CONFIG.batch_size, seed=100 + rank).batch


def joined(batches: list[TrainingBatch]) -> TrainingBatch:
    """The batches as one batch, in order."""
    parts = {f.name: torch.cat([getattr(b, f.name) for b in batches]) for f in fields(batches[0])}
    return TrainingBatch(**parts)


def gradients(
    network: DistributionNetwork, model: torch.nn.Module, batch: TrainingBatch, mode: str
) -> list[torch.Tensor]:
    """Every parameter's gradient of the training loss on ``batch``, ``model`` calling
    ``network`` (itself, or its DDP wrapper) in ``mode``."""
    network.train(mode == "train")
    network.zero_grad(set_to_none=True)
    weights = build_schedule(CONFIG).weights_at(0)
    terms = compute_losses(model(batch.proxy), batch, BodyModel(), weights, CONFIG.num_samples)
    terms["total"].backward()
    return [parameter.grad.detach().clone() for parameter in network.parameters()]


def main(out: str) -> None:
    launch = detect_launch()
    device = torch.device("cpu")
    start_process_group(launch, device)
    network = tiny_network()
    model = wrap_for_training(network, launch, device)
    batch = rank_batch(launch.rank)
    found = {mode: gradients(network, model, batch, mode) for mode in MODES}
    if launch.is_main:
        torch.save(found, out)
    end_process_group(wait_for_all=True)


if __name__ == "__main__":
    main(sys.argv[1])

"""The fixed synthetic test set: a checkpoint's network and a generator of held-out examples.

``hkpd-eval``, ``hkpd-tune-evidence`` and the experiments in ``docs/`` all score a network on
examples rendered from one split of the pose bank with a fixed seed, at the network's own input
size (:func:`network_and_generator`, then :func:`fixed_batches`), so every run sees exactly the
same examples.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import torch

from hkpd.body import BodyModel
from hkpd.conditioning import EvidenceConfig
from hkpd.network import DistributionNetwork
from hkpd.network.checkpoint import load_network, read_checkpoint, stored_evidence_config
from hkpd.poses import pose_source
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.batch import TrainingBatch
from hkpd.synthesis.generator import (
    SyntheticDataConfig,
    SyntheticDataGenerator,
    iter_fixed_test_set,
)
from hkpd.synthesis.orientation import OrientationMix

TEST_SET_SEED = 2021
"""Seed of the synthetic test set (``hkpd-eval``)."""

TEST_BATCH_SIZE = 50
"""Examples rendered per batch."""


def stored_evidence_settings(checkpoint: Path) -> EvidenceConfig:
    """The evidence settings stored with ``checkpoint`` (``hkpd-tune-evidence --write-to``; the
    defaults when it stores none), as :meth:`hkpd.prediction.Predictor.from_pretrained` takes
    them, so the synthetic evidence rows and the photo rows score the same posterior.

    Raises:
        FileNotFoundError, CheckpointError: as :func:`hkpd.network.checkpoint.read_checkpoint`.
        ValueError: the stored settings are not valid, naming the file.
    """
    payload = read_checkpoint(checkpoint)
    return EvidenceConfig.from_dict(stored_evidence_config(payload), str(checkpoint))


def network_and_generator(
    checkpoint: Path,
    poses: Path | None,
    device: torch.device | str,
    *,
    split: str = "test",
    augmentation: AugmentationConfig | None = None,
    orientation: OrientationMix | None = None,
) -> tuple[DistributionNetwork, SyntheticDataGenerator]:
    """The checkpoint's network (eval mode) and a generator of examples at its input size.

    Args:
        checkpoint: a checkpoint written by ``hkpd-train`` or the shipped weights.
        poses: the pose bank; None: procedural poses.
        device: where the network, the body model and the renderer run.
        split: the pose bank's split the poses come from (``"test"``: held-out subjects;
            ``"val"`` for tuning).
        augmentation: the generator's augmentations (default: the training ones).
        orientation: how views are rolled (default: upright people).

    Returns:
        The network and the generator (its ``body`` is the body model on ``device``).
    """
    network, _ = load_network(checkpoint, device)
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size), image_proxy=network.config.image_proxy
    )
    if augmentation is not None:
        config = replace(config, augmentation=augmentation)
    if orientation is not None:
        config = replace(config, orientation=orientation)
    body = BodyModel().to(device)
    generator = SyntheticDataGenerator(pose_source(poses, split), config, device, body=body)
    return network, generator


def fixed_batches(
    generator: SyntheticDataGenerator, count: int, seed: int = TEST_SET_SEED
) -> Iterator[TrainingBatch]:
    """The ``count`` fixed examples of ``generator`` with ``seed``, :data:`TEST_BATCH_SIZE` at a
    time."""
    return iter_fixed_test_set(generator, count, seed, TEST_BATCH_SIZE)

"""hkpd.evaluation.test_set: the network of a checkpoint and its fixed synthetic test set."""

from __future__ import annotations

import torch
from test_evaluation_cli import tiny_checkpoint

from hkpd.evaluation.test_set import TEST_SET_SEED, fixed_batches, network_and_generator
from hkpd.synthesis.augmentations import AugmentationConfig
from hkpd.synthesis.generator import iter_fixed_test_set


def test_the_test_set_is_fixed_and_at_the_networks_own_input_size(tmp_path) -> None:
    checkpoint = tiny_checkpoint(tmp_path)
    network, generator = network_and_generator(checkpoint, None, "cpu")
    assert not network.training and generator.config.image_size == 64
    assert generator.body is not None
    first = [batch.proxy for batch in fixed_batches(generator, 3)]
    again = [batch.proxy for batch in iter_fixed_test_set(generator, 3, TEST_SET_SEED, 50)]
    assert len(first) == 1 and tuple(first[0].shape) == (3, 18, 64, 64)
    torch.testing.assert_close(first[0], again[0], rtol=0, atol=0)
    other_seed = next(iter(fixed_batches(generator, 3, seed=TEST_SET_SEED + 1))).proxy
    assert not torch.equal(other_seed, first[0])
    _, plain = network_and_generator(
        checkpoint, None, "cpu", augmentation=AugmentationConfig.disabled()
    )
    assert plain.config.augmentation == AugmentationConfig.disabled()

"""Checkpoints as the training loop uses them; the format lives beside the network.

Reading and writing weights is :mod:`hkpd.network.checkpoint` (so prediction and evaluation
load weights without importing the training stack); this module keeps the training-side names
where they always were.
"""

from hkpd.network.checkpoint import (
    FORMAT,
    VERSION,
    CheckpointError,
    load_initial_weights,
    load_network,
    model_checksum,
    random_states,
    read_checkpoint,
    restore_random_states,
    save_checkpoint,
)

__all__ = [
    "FORMAT",
    "VERSION",
    "CheckpointError",
    "load_initial_weights",
    "load_network",
    "model_checksum",
    "random_states",
    "read_checkpoint",
    "restore_random_states",
    "save_checkpoint",
]

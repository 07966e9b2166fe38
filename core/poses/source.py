"""The interface every source of training poses implements."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import torch


@runtime_checkable
class PoseSource(Protocol):
    """Something that draws SMPL poses for synthetic training data.

    Implementations: :class:`hkpd.poses.PoseBank` (retargeted mocap) and
    :class:`hkpd.poses.ProceduralPosePrior` (random poses within anatomical limits).
    """

    def sample(self, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """Draw ``count`` poses using only ``generator`` for randomness (same generator state,
        same poses).

        Returns:
            ``body_pose (count, 23, 3, 3)``: rotations of the 23 body joints relative to their
            parents; ``global_orient (count, 3, 3)``: the body's orientation in the mocap world
            (SMPL axes, Y up; identity = upright facing +Z), to be composed with a camera view.
            Both float32 on the CPU.
        """
        ...

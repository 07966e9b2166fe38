"""``KeypointEvidence``: the 2D keypoints a fit conditions on, in the network's crop."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.coco_keypoints import COCO17_NAMES


@dataclass(frozen=True)
class KeypointEvidence:
    """COCO-17 keypoints observed in the network's crop.

    Attributes:
        keypoints: ``(17, 2)`` crop pixels (``(u, v)``, pixel centres at integers).
        observed: ``(17,)`` bool, True where the keypoint is evidence.
        crop_size: side of the crop in pixels.
    """

    keypoints: torch.Tensor
    observed: torch.Tensor
    crop_size: int

    @property
    def count(self) -> int:
        """Number of evidence keypoints."""
        return int(self.observed.sum())

    def names(self) -> list[str]:
        """Names of the evidence keypoints (COCO order)."""
        return [
            name for name, seen in zip(COCO17_NAMES, self.observed.tolist(), strict=True) if seen
        ]

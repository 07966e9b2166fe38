"""The square crop box around a person, shared by synthetic data and the photo predictor."""

from __future__ import annotations

import torch

CROP_MARGIN = 1.2
"""Side of the square box as a multiple of the keypoints' bounding-box extent (the larger side).

COCO keypoints stop at the eyes/ears and ankles, so the margin also makes room for the top of
the head and the feet."""


def square_box_around_keypoints(
    keypoints: torch.Tensor, present: torch.Tensor, margin: float = CROP_MARGIN
) -> tuple[torch.Tensor, torch.Tensor]:
    """Square box centred on the keypoints' bounding box.

    Args:
        keypoints: ``(B, J, 2)`` pixel coordinates.
        present: ``(B, J)`` bool, the keypoints that count; each row needs at least two.
        margin: side = ``margin * max(width, height)`` of their bounding box.

    Returns:
        ``centre (B, 2)`` and ``side (B,)`` in the same pixels.

    Raises:
        ValueError: some row has fewer than two present keypoints.
    """
    counts = present.sum(-1)
    if bool((counts < 2).any()):
        raise ValueError("a crop box needs at least two keypoints per person")
    big = torch.finfo(keypoints.dtype).max
    mask = present.unsqueeze(-1)
    lower = torch.where(mask, keypoints, big).amin(1)
    upper = torch.where(mask, keypoints, -big).amax(1)
    centre = (lower + upper) / 2
    side = margin * (upper - lower).amax(-1).clamp_min(1.0)
    return centre, side

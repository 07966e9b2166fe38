"""Gaussian joint heatmaps, channels 1-17 of the proxy representation."""

from __future__ import annotations

import torch

HEATMAP_STD_AT_256 = 4.0
"""Standard deviation of each joint's Gaussian, in pixels of a 256-pixel crop."""


def heatmap_std(image_size: int) -> float:
    """The Gaussian's standard deviation in pixels for a crop of ``image_size`` pixels."""
    return HEATMAP_STD_AT_256 * image_size / 256.0


def joint_heatmaps(
    keypoints: torch.Tensor,
    present: torch.Tensor,
    image_size: int,
    out: torch.Tensor | None = None,
) -> torch.Tensor:
    """One unnormalised Gaussian per joint, peak 1 at the joint, zero for absent joints.

    The Gaussian is separable, so each map is the outer product of a row and a column profile:
    no ``(B, J, H, W)`` distance tensor is formed before the output itself.

    Args:
        keypoints: ``(B, J, 2)`` joint positions ``(u, v)`` in crop pixels (pixel centres at
            integer coordinates).
        present: ``(B, J)`` bool; False gives an all-zero map.
        image_size: side of the square crop in pixels.
        out: optional ``(B, J, image_size, image_size)`` float32 tensor (may be a channel slice
            of a larger tensor) to write into, which saves a copy of the largest array.

    Returns:
        ``(B, J, image_size, image_size)`` float32 on ``keypoints``' device, in [0, 1].
    """
    std = heatmap_std(image_size)
    grid = torch.arange(image_size, device=keypoints.device, dtype=torch.float32)
    offsets = grid.view(1, 1, 1, -1) - keypoints.float().unsqueeze(-1)  # (B, J, 2, S)
    profiles = torch.exp(offsets.square() * (-0.5 / std**2))
    columns = profiles[:, :, 0] * present.to(profiles.dtype).unsqueeze(-1)  # (B, J, S) along u
    rows = profiles[:, :, 1]  # (B, J, S) along v
    if out is None:
        return rows.unsqueeze(-1) * columns.unsqueeze(-2)
    return torch.mul(rows.unsqueeze(-1), columns.unsqueeze(-2), out=out)

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


def heatmap_peaks(heatmaps: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The joint positions that :func:`joint_heatmaps` drew, read back from the maps.

    The brightest pixel of each map, refined to sub-pixel precision along each axis by the
    parabola through the logarithms of it and its two neighbours (exact for a Gaussian whose
    neighbours lie inside the crop).

    Args:
        heatmaps: ``(B, J, S, S)`` maps, peak 1 at each drawn joint, all zero for absent ones.

    Returns:
        ``(B, J, 2)`` float32 ``(u, v)`` crop pixels, and ``(B, J)`` bool: which maps hold a
        joint (an absent joint's position is 0).
    """
    count, joints, size, _ = heatmaps.shape
    flat = heatmaps.reshape(count, joints, -1)
    peak, index = flat.max(-1)
    present = peak > 0.5
    rows, columns = index // size, index % size
    floor = torch.finfo(torch.float32).tiny

    def refined(along_rows: bool) -> torch.Tensor:
        centre = rows if along_rows else columns
        before, after = (centre - 1).clamp(0, size - 1), (centre + 1).clamp(0, size - 1)
        at = (
            (lambda r: r * size + columns) if along_rows else (lambda c: rows * size + c)
        )  # flat index of the neighbour along the chosen axis
        values = [flat.gather(-1, at(i)[..., None])[..., 0] for i in (before, centre, after)]
        low, middle, high = (v.float().clamp_min(floor).log() for v in values)
        curvature = low - 2 * middle + high
        inside = (centre > 0) & (centre < size - 1) & (curvature < 0)
        shift = torch.where(inside, 0.5 * (low - high) / curvature.where(inside, -1.0), 0.0)
        return centre.float() + shift.clamp(-0.5, 0.5)

    points = torch.stack([refined(False), refined(True)], -1)
    return points * present[..., None], present

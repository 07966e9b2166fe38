"""The proxy representation: one code path for synthetic training images and real photos.

Channel 0 is the Canny edge image of the RGB crop; channels 1-17 are Gaussian heatmaps of the
COCO-17 joints, with joints whose detector confidence is below ``CONFIDENCE_THRESHOLD`` left
out (all-zero maps), as in the paper.
"""

from __future__ import annotations

import numpy as np
import torch

from hkpd.proxy.edges import canny_edge_bits
from hkpd.proxy.heatmaps import joint_heatmaps

CONFIDENCE_THRESHOLD = 0.6
"""Joints detected with a lower confidence are dropped from the heatmaps (paper, Section 3.1)."""

NUM_KEYPOINTS = 17
PROXY_CHANNELS = 1 + NUM_KEYPOINTS


def joints_kept(confidences: torch.Tensor | np.ndarray) -> torch.Tensor:
    """``(..., 17)`` bool: which joints are confident enough to enter the proxy."""
    return torch.as_tensor(confidences) >= CONFIDENCE_THRESHOLD


def build_proxy_batch(
    images: np.ndarray | torch.Tensor,
    keypoints: torch.Tensor,
    present: torch.Tensor,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Proxy representations of a batch of square RGB crops.

    Args:
        images: ``(B, S, S, 3)`` uint8 RGB crops (numpy, or a CPU/GPU tensor).
        keypoints: ``(B, 17, 2)`` joint positions in crop pixels.
        present: ``(B, 17)`` bool, the joints to draw (e.g. ``joints_kept(confidences)``).
        device: where the result lives; defaults to ``keypoints``' device.

    Returns:
        ``(B, 18, S, S)`` float32: edges in {0, 1}, then 17 heatmaps in [0, 1].

    Raises:
        ValueError: on inconsistent shapes.
    """
    return assemble_proxy(edge_bits_batch(images), keypoints, present, device)


def edge_bits_batch(images: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Canny edges of a batch of square RGB crops, the proxy's first channel in compact form.

    Args:
        images: ``(B, S, S, 3)`` uint8 RGB crops (numpy, or a CPU/GPU tensor).

    Returns:
        ``(B, S, S)`` uint8 in {0, 1}, on the CPU.

    Raises:
        ValueError: the images are not square RGB crops.
    """
    images_np = images.cpu().numpy() if isinstance(images, torch.Tensor) else np.asarray(images)
    if images_np.ndim != 4 or images_np.shape[-1] != 3 or images_np.shape[1] != images_np.shape[2]:
        raise ValueError(f"images must be (B, S, S, 3) uint8 RGB, got {images_np.shape}")
    edges = np.empty(images_np.shape[:3], dtype=np.uint8)
    for index, image in enumerate(images_np):
        edges[index] = canny_edge_bits(image)
    return torch.from_numpy(edges)


def assemble_proxy(
    edge_bits: torch.Tensor,
    keypoints: torch.Tensor,
    present: torch.Tensor,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """The float proxy from edge bits and keypoints (the heatmaps are drawn here).

    Args:
        edge_bits: ``(B, S, S)`` uint8 (or bool) edge images, e.g. from :func:`edge_bits_batch`.
        keypoints: ``(B, 17, 2)`` joint positions in crop pixels.
        present: ``(B, 17)`` bool, the joints to draw.
        device: where the result lives; defaults to ``keypoints``' device.

    Returns:
        ``(B, 18, S, S)`` float32: edges in {0, 1}, then 17 heatmaps in [0, 1].

    Raises:
        ValueError: on inconsistent shapes.
    """
    if edge_bits.dim() != 3 or edge_bits.shape[1] != edge_bits.shape[2]:
        raise ValueError(f"edge images must be (B, S, S), got {tuple(edge_bits.shape)}")
    count, size = edge_bits.shape[0], edge_bits.shape[1]
    if keypoints.shape != (count, NUM_KEYPOINTS, 2) or present.shape != (count, NUM_KEYPOINTS):
        raise ValueError(
            f"keypoints must be ({count}, 17, 2) and present ({count}, 17); got "
            f"{tuple(keypoints.shape)} and {tuple(present.shape)}"
        )
    device = keypoints.device if device is None else torch.device(device)
    proxy = torch.empty(count, PROXY_CHANNELS, size, size, device=device)
    proxy[:, 0] = edge_bits.to(device)
    joint_heatmaps(keypoints.to(device), present.to(device), size, out=proxy[:, 1:])
    return proxy


def build_proxy(
    image: np.ndarray, keypoints: np.ndarray | torch.Tensor, confidences: np.ndarray | torch.Tensor
) -> torch.Tensor:
    """Proxy representation of one square RGB crop from detected keypoints.

    Args:
        image: ``(S, S, 3)`` uint8 RGB crop.
        keypoints: ``(17, 2)`` COCO keypoints in crop pixels.
        confidences: ``(17,)`` detector confidences in [0, 1]; joints below
            ``CONFIDENCE_THRESHOLD`` are dropped.

    Returns:
        ``(18, S, S)`` float32 on the CPU.
    """
    points = torch.as_tensor(np.asarray(keypoints), dtype=torch.float32).reshape(1, -1, 2)
    kept = joints_kept(np.asarray(confidences, dtype=np.float32)).reshape(1, -1)
    return build_proxy_batch(np.asarray(image)[None], points, kept)[0]

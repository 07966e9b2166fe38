"""Canny edge images, the first channel of the proxy representation."""

from __future__ import annotations

import cv2
import numpy as np

CANNY_LOW_THRESHOLD = 100
"""Hysteresis low threshold on the 8-bit grey image's gradient magnitude."""

CANNY_HIGH_THRESHOLD = 200
"""Hysteresis high threshold; edges start at pixels whose gradient exceeds it."""


def canny_edges(image_rgb: np.ndarray) -> np.ndarray:
    """Binary edge image of an RGB image.

    Args:
        image_rgb: ``(H, W, 3)`` uint8 RGB.

    Returns:
        ``(H, W)`` float32 in {0, 1}.

    Raises:
        ValueError: the image is not ``(H, W, 3)`` uint8.
    """
    return canny_edge_bits(image_rgb).astype(np.float32)


def canny_edge_bits(image_rgb: np.ndarray) -> np.ndarray:
    """Like :func:`canny_edges` but ``(H, W)`` uint8 in {0, 1}: a quarter of the bytes, for
    passing edge images between processes before they become float proxy channels."""
    if image_rgb.dtype != np.uint8 or image_rgb.ndim != 3 or image_rgb.shape[2] != 3:
        raise ValueError(
            f"canny_edges needs an (H, W, 3) uint8 RGB image, got shape {image_rgb.shape} "
            f"and dtype {image_rgb.dtype}"
        )
    grey = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2GRAY)
    edges = cv2.Canny(grey, CANNY_LOW_THRESHOLD, CANNY_HIGH_THRESHOLD)
    return (edges > 0).view(np.uint8)

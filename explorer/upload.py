"""Checking photos that users upload through the browser before they reach the predictor."""

from __future__ import annotations

from pathlib import PurePath

import cv2
import numpy as np

MAX_UPLOAD_BYTES = 25 * 1024 * 1024
"""Uploads larger than this are refused."""

ALLOWED_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff")

MIN_SIDE = 32
"""Photos smaller than this (pixels) cannot show a person well enough to predict."""


class UploadError(ValueError):
    """An upload that cannot be used; the message is shown to the user as is."""


def decode_upload(name: str, content: bytes) -> np.ndarray:
    """Validate and decode an uploaded photo.

    Args:
        name: the file name the browser sent (only its suffix is used).
        content: the file's bytes.

    Returns:
        ``(H, W, 3)`` uint8 RGB.

    Raises:
        UploadError: wrong type, empty, too large, undecodable or too small.
    """
    suffix = PurePath(name).suffix.lower()
    if suffix not in ALLOWED_SUFFIXES:
        raise UploadError(
            f"{name!r} is not a supported photo; use one of {', '.join(ALLOWED_SUFFIXES)}"
        )
    if not content:
        raise UploadError(f"{name!r} is empty")
    if len(content) > MAX_UPLOAD_BYTES:
        raise UploadError(
            f"{name!r} is {len(content) / 2**20:.1f} MiB; the limit is "
            f"{MAX_UPLOAD_BYTES / 2**20:.0f} MiB"
        )
    decoded = cv2.imdecode(np.frombuffer(content, dtype=np.uint8), cv2.IMREAD_COLOR)
    if decoded is None:
        raise UploadError(f"{name!r} could not be decoded as an image (corrupt or not a photo)")
    height, width = decoded.shape[:2]
    if min(height, width) < MIN_SIDE:
        raise UploadError(f"{name!r} is only {width}x{height} pixels; need at least {MIN_SIDE}")
    return cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB)

"""Checking photos that users upload through the browser before they reach the predictor.

Decoding is bounded: the pixel count is checked from the file's header before any pixel is
decoded (:data:`hkpd.prediction.image_input.MAX_IMAGE_PIXELS`), and one upload is decoded at a
time (a lock), so several large uploads arriving at once cost one decode's memory, not several.
"""

from __future__ import annotations

import re
import threading
from pathlib import PurePath

import numpy as np
from PIL import Image

from hkpd.prediction.image_input import IMAGE_SUFFIXES, ImageInputError, load_image

MAX_UPLOAD_BYTES = 25 * 1024 * 1024
"""Uploads larger than this are refused."""

ALLOWED_SUFFIXES = IMAGE_SUFFIXES

_DECODE_LOCK = threading.Lock()
"""One decode at a time, across every tab and every upload callback thread."""


class UploadError(ValueError):
    """An upload that cannot be used; the message is shown to the user as is."""


def decode_upload(name: str, content: bytes) -> np.ndarray:
    """Validate and decode an uploaded photo (one at a time; see the module docstring).

    Args:
        name: the file name the browser sent (only its suffix is used).
        content: the file's bytes.

    Returns:
        ``(H, W, 3)`` uint8 RGB, EXIF orientation applied, huge photos downscaled as
        :func:`hkpd.prediction.load_image` does.

    Raises:
        UploadError: wrong type, empty, too large (bytes or pixels), undecodable (corrupt,
            truncated, not an image, a decompression bomb, out of memory) or too small.
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
    try:
        with _DECODE_LOCK:
            loaded = load_image(content)
    except ImageInputError as error:  # the reason says what is wrong and what to do
        if error.__cause__ is None or isinstance(error.__cause__, Image.DecompressionBombError):
            raise UploadError(f"{name!r} cannot be used: {_plain_reason(error)}") from error
        raise UploadError(
            f"{name!r} could not be read as an image: {_plain_reason(error)}"
        ) from error
    except Exception as error:  # any other decoder failure: still a message, not a traceback
        raise UploadError(
            f"{name!r} could not be read as an image (corrupt, truncated or not a photo)"
        ) from error
    return np.ascontiguousarray(loaded.pixels)


_INTERNAL_LABELS = re.compile(
    r"^(array \([^)]*\) \w+|PIL image[^:]*|image file contents \([^)]*\)|<[^>]*>):\s*"
)


def _plain_reason(error: Exception) -> str:
    """The reason without the in-memory source label (``array (480, 640, 3) uint8: ...``)."""
    return _INTERNAL_LABELS.sub("", str(error))

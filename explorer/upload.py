"""Checking photos that users upload through the browser before they reach the predictor."""

from __future__ import annotations

import io
import re
from pathlib import PurePath

import numpy as np
from PIL import Image, UnidentifiedImageError

from hkpd.prediction.image_input import IMAGE_SUFFIXES, ImageInputError, load_image

MAX_UPLOAD_BYTES = 25 * 1024 * 1024
"""Uploads larger than this are refused."""

ALLOWED_SUFFIXES = IMAGE_SUFFIXES


class UploadError(ValueError):
    """An upload that cannot be used; the message is shown to the user as is."""


def decode_upload(name: str, content: bytes) -> np.ndarray:
    """Validate and decode an uploaded photo.

    Args:
        name: the file name the browser sent (only its suffix is used).
        content: the file's bytes.

    Returns:
        ``(H, W, 3)`` uint8 RGB, EXIF orientation applied, huge photos downscaled as
        :func:`hkpd.prediction.load_image` does.

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
    try:
        with Image.open(io.BytesIO(content)) as opened:
            opened.load()
            loaded = load_image(opened)
    except (UnidentifiedImageError, OSError) as error:
        raise UploadError(
            f"{name!r} could not be read as an image (corrupt, truncated or not a photo)"
        ) from error
    except ImageInputError as error:  # readable, but unusable (e.g. too small)
        raise UploadError(f"{name!r} cannot be used: {_plain_reason(error)}") from error
    return np.ascontiguousarray(loaded.pixels)


_INTERNAL_LABELS = re.compile(r"^(array \([^)]*\) \w+|PIL image[^:]*|<[^>]*>):\s*")


def _plain_reason(error: Exception) -> str:
    """The reason without the in-memory source label (``array (480, 640, 3) uint8: ...``)."""
    return _INTERNAL_LABELS.sub("", str(error))

"""Read a photo from whatever the user has into one ``(H, W, 3)`` uint8 RGB array.

:func:`load_image` accepts a file path, a file's bytes, a numpy array or a PIL image and
returns a :class:`LoadedImage`: the RGB pixels the predictor works on plus what is needed to map
coordinates back to the *original* photo.

What it does to the input, in order:

1. **EXIF orientation** (files and PIL images) is applied, so the pixels are the photo as a viewer
   displays it. "Original image pixels" everywhere in :mod:`hkpd.prediction` means this
   displayed, rotated image at full resolution.
2. **Colour**: grayscale is repeated into three channels; palette images are expanded; CMYK,
   YCbCr and the like are converted by PIL; images with **transparency** (RGBA, LA, palette with a
   transparent colour) are composited **on white** (``rgb * alpha + 255 * (1 - alpha)``), the way
   image viewers show them, because transparent pixels of cut-outs often hold arbitrary colours.
3. **Bit depth**: 16-bit images (uint16 arrays, 16-bit PNG/TIFF, also colour ones, which PIL
   alone would truncate) are scaled with rounding, ``round(x * 255 / 65535)``.
4. **Size**: images with more than :data:`MAX_IMAGE_PIXELS` pixels are refused (files before
   their pixels are decoded: the size comes from the header); images whose shorter side is below
   :data:`MIN_IMAGE_SIDE` are refused; images whose longer side exceeds ``max_side``
   (:data:`MAX_IMAGE_SIDE` by default) are downscaled with area averaging so that it equals
   ``max_side``. :meth:`LoadedImage.to_original` maps points back.

Pixel coordinates follow :mod:`hkpd.camera_conventions`: ``(u, v)``, u right, v down, pixel
centres at integer coordinates.
"""

from __future__ import annotations

import io
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from PIL import Image, ImageOps, UnidentifiedImageError

from hkpd.prediction.pixel_maps import Points, scale_and_shift

MAX_IMAGE_SIDE = 4096
"""Default cap on the longer side of the working image, in pixels; larger photos are downscaled.
The network only sees a 256-pixel crop, so more resolution buys nothing but memory and time."""

MIN_IMAGE_SIDE = 32
"""Smallest accepted shorter side, in pixels: below this there is no person to see."""

MAX_IMAGE_PIXELS = 50_000_000
"""Largest accepted image, in pixels (width x height), for files, bytes, arrays and PIL images.
50 Mpx holds every ordinary photo (a 45 Mpx full-frame camera is 8192x5464; phones save 12-50
Mpx) while its decode stays bounded: about 200 MB for RGBA pixels, against 2.4 GB for the
177 Mpx that PIL's own bomb check (179 Mpx) still lets through. Files are checked from their
header, before any pixel is decoded."""

_EXIF_ORIENTATION_TAG = 0x0112


IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".webp", ".tif", ".tiff")
"""File suffixes (any case) taken as photos by the command line and the explorer's upload."""


class ImageInputError(ValueError):
    """The input is not an image the predictor can use; the message says why and what to do."""


SOURCE_SHOWN = 60
"""Characters of a photo's source (its end: the file name) that the records' reprs show."""


def short_source(source: str, limit: int = SOURCE_SHOWN) -> str:
    """``source`` cut to its last ``limit`` characters (``…`` in front when cut), for a repr."""
    return source if len(source) <= limit else "…" + source[-(limit - 1) :]


@dataclass(frozen=True, eq=False)
class LoadedImage:
    """An RGB photo ready for detection, plus the map back to the original photo's pixels.

    Attributes:
        pixels: ``(H, W, 3)`` uint8 RGB, C-contiguous: the working image (downscaled when the
            original was larger than the ``max_side`` it was loaded with).
        original_size: ``(width, height)`` of the original photo after EXIF orientation.
        source: where it came from (a path, or a description of the object), for messages.

    ``np.asarray(loaded)`` gives :attr:`pixels`.
    """

    pixels: np.ndarray
    original_size: tuple[int, int]
    source: str

    def __repr__(self) -> str:
        """One line of at most 200 characters: the sizes and the source's end (never the
        pixels)."""
        width, height = self.size
        original = "" if not self.was_downscaled else " of {}x{}".format(*self.original_size)
        return f"LoadedImage({width}x{height} RGB{original}, source={short_source(self.source)!r})"

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of :attr:`pixels`."""
        return self.pixels.shape[1], self.pixels.shape[0]

    @property
    def scale(self) -> tuple[float, float]:
        """Per-axis ``working / original`` size ratio; ``(1.0, 1.0)`` when not downscaled."""
        return self.size[0] / self.original_size[0], self.size[1] / self.original_size[1]

    @property
    def was_downscaled(self) -> bool:
        """Whether :attr:`pixels` is smaller than the original photo."""
        return self.size != self.original_size

    def to_original(self, points: Points) -> Points:
        """Map ``(..., 2)`` working-image pixel coordinates to original-photo pixel coordinates.

        With pixel centres at integers, ``original = (working + 0.5) / scale - 0.5`` per axis.
        """
        sx, sy = self.scale
        return scale_and_shift(points, (1 / sx, 1 / sy), (0.5 / sx - 0.5, 0.5 / sy - 0.5))

    def from_original(self, points: Points) -> Points:
        """Inverse of :meth:`to_original`: original-photo pixels to working-image pixels."""
        sx, sy = self.scale
        return scale_and_shift(points, (sx, sy), (0.5 * sx - 0.5, 0.5 * sy - 0.5))

    def with_pixels(self, pixels: np.ndarray) -> LoadedImage:
        """The same photo with replaced working pixels of the same shape (e.g. occluded)."""
        if pixels.shape != self.pixels.shape or pixels.dtype != np.uint8:
            raise ValueError(
                f"replacement pixels must be {self.pixels.shape} uint8, "
                f"got {pixels.shape} {pixels.dtype}"
            )
        return LoadedImage(np.ascontiguousarray(pixels), self.original_size, self.source)

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        return self.pixels if dtype is None else self.pixels.astype(dtype)


def load_image(
    image: str | os.PathLike[str] | bytes | np.ndarray | Image.Image | LoadedImage,
    max_side: int = MAX_IMAGE_SIDE,
) -> LoadedImage:
    """Load a photo as ``(H, W, 3)`` uint8 RGB (see the module docstring for every step).

    Args:
        image: a path to an image file (anything PIL reads: JPEG, PNG, TIFF, WebP, BMP, ...);
            the bytes of such a file (an upload); a numpy array ``(H, W)`` grayscale,
            ``(H, W, 1)``, ``(H, W, 2)`` grayscale + alpha,
            ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA, of dtype uint8 or uint16 (arrays are taken as
            RGB, not OpenCV's BGR); a PIL image; or an already loaded image (returned as is when
            it fits ``max_side``).
        max_side: longest side of the returned pixels; larger images are downscaled.

    Returns:
        The :class:`LoadedImage`.

    Raises:
        ImageInputError: missing or unreadable file, corrupt or truncated data, not an image,
            unsupported array shape or dtype, more than :data:`MAX_IMAGE_PIXELS` pixels (checked
            before decoding), or an image smaller than :data:`MIN_IMAGE_SIDE`.
    """
    if max_side < MIN_IMAGE_SIDE:
        raise ValueError(f"max_side must be at least {MIN_IMAGE_SIDE}, got {max_side}")
    if isinstance(image, LoadedImage):
        if max(image.size) <= max_side:
            return image
        return _fit(image.pixels, image.source, max_side, image.original_size)
    if isinstance(image, (str, os.PathLike)):
        source = str(image)
        rgb = _decode(_read_file(Path(image)), source)
    elif isinstance(image, (bytes, bytearray, memoryview)):
        source = f"image file contents ({len(image)} bytes)"
        rgb = _decode(bytes(image), source)
    elif isinstance(image, Image.Image):
        source = f"PIL image ({image.mode}, {image.width}x{image.height})"
        check_pixel_count(image.size, source)
        rgb = _rgb8_from_pil(ImageOps.exif_transpose(image), source)
    elif isinstance(image, np.ndarray):
        source = f"array {image.shape} {image.dtype}"
        if image.ndim >= 2:
            check_pixel_count((image.shape[1], image.shape[0]), source)
        rgb = _rgb8_from_array(image, source)
    else:
        raise ImageInputError(
            f"cannot read an image from a {type(image).__name__}; pass a file path, the file's "
            "bytes, a numpy array (H, W, 3) uint8 RGB, or a PIL image"
        )
    height, width = rgb.shape[:2]
    if min(width, height) < MIN_IMAGE_SIDE:
        raise ImageInputError(
            f"{source}: the image is only {width}x{height} pixels; at least "
            f"{MIN_IMAGE_SIDE} pixels per side are needed, and a person should be a few hundred "
            "pixels tall for a useful result. Use a larger photo."
        )
    return _fit(rgb, source, max_side, (width, height))


def _fit(
    rgb: np.ndarray, source: str, max_side: int, original_size: tuple[int, int]
) -> LoadedImage:
    """Downscale ``rgb`` (area averaging) so that its longer side is at most ``max_side``."""
    height, width = rgb.shape[:2]
    if max(width, height) > max_side:
        factor = max_side / max(width, height)
        new_size = (max(1, round(width * factor)), max(1, round(height * factor)))
        rgb = cv2.resize(rgb, new_size, interpolation=cv2.INTER_AREA)
    return LoadedImage(np.ascontiguousarray(rgb), original_size, source)


def check_pixel_count(size: tuple[int, int], source: str) -> None:
    """Refuse an image of ``size = (width, height)`` with more than :data:`MAX_IMAGE_PIXELS`.

    Raises:
        ImageInputError: naming ``source``, its size and the limit.
    """
    width, height = int(size[0]), int(size[1])
    if width * height > MAX_IMAGE_PIXELS:
        raise ImageInputError(
            f"{source}: the image is {width}x{height} = {width * height / 1e6:.0f} megapixels; "
            f"at most {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels are accepted (a safe decode). "
            f"Downscale it first, e.g. to at most {MAX_IMAGE_SIDE} pixels per side."
        )


def _read_file(path: Path) -> bytes:
    """The contents of an image file (not yet decoded)."""
    if not path.exists():
        raise ImageInputError(
            f"{path}: no such file; check the path (relative paths start at {Path.cwd()})"
        )
    if path.is_dir():
        raise ImageInputError(f"{path} is a directory; pass the path of one image file")
    try:
        return path.read_bytes()
    except OSError as error:
        raise ImageInputError(f"{path}: cannot read the file ({error})") from error


def _decode(data: bytes, source: str) -> np.ndarray:
    """Decode an image file's bytes into ``(H, W, 3)`` uint8 RGB with EXIF orientation applied.

    The pixel count is checked from the header (``Image.open`` reads only the header) before
    anything is decoded; every decoding failure becomes an :class:`ImageInputError`.
    """
    if not data:
        raise ImageInputError(f"{source}: the file is empty; it is not an image")
    try:
        with warnings.catch_warnings():  # our own, lower limit is checked next
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            pil = Image.open(io.BytesIO(data))
        with pil:
            check_pixel_count(pil.size, source)
            # Read the raw mode first: getexif() may decode the image and clear the tiles.
            raw_mode = pil.tile[0][3] if pil.tile and isinstance(pil.tile[0][3], str) else ""
            orientation = pil.getexif().get(_EXIF_ORIENTATION_TAG, 1)
            pil.load()
            if pil.mode in ("RGB", "RGBA") and ";16" in raw_mode:
                # PIL keeps only the high byte of 16-bit colour; decode the full depth with OpenCV.
                rgb = _rgb8_from_array(_decode_16bit_colour(data, source), source)
            else:
                rgb = _rgb8_from_pil(pil, source)
    except (UnidentifiedImageError, Image.DecompressionBombError) as error:
        raise ImageInputError(_unreadable_message(source, error)) from error
    except MemoryError as error:
        raise ImageInputError(
            f"{source}: not enough memory to decode this image; downscale it first"
        ) from error
    except (OSError, SyntaxError, ValueError, EOFError) as error:
        if isinstance(error, ImageInputError):
            raise
        raise ImageInputError(
            f"{source}: the image data is corrupt or truncated ({error}); re-export or "
            "re-download the photo"
        ) from error
    return _apply_orientation(rgb, orientation)


def _unreadable_message(source: str, error: Exception) -> str:
    if isinstance(error, Image.DecompressionBombError):
        return (
            f"{source}: the image has far more than the {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels "
            f"accepted ({error}); downscale it first, e.g. to at most {MAX_IMAGE_SIDE} pixels "
            "per side"
        )
    return (
        f"{source}: not a readable image file (PIL cannot identify its format); pass a JPEG, "
        "PNG, TIFF, WebP or BMP photo (convert HEIC/HEIF phone photos to JPEG first)"
    )


def _decode_16bit_colour(data: bytes, source: str) -> np.ndarray:
    """``(H, W, 3|4)`` uint16 RGB(A) from an encoded 16-bit colour image."""
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if decoded is None or decoded.ndim != 3:
        raise ImageInputError(f"{source}: cannot decode this 16-bit colour image")
    code = cv2.COLOR_BGRA2RGBA if decoded.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(decoded, code)


def _apply_orientation(rgb: np.ndarray, orientation: int) -> np.ndarray:
    """Apply an EXIF orientation (1-8) to ``(H, W, C)`` pixels, as a viewer displays them."""
    transforms = {
        2: lambda a: a[:, ::-1],
        3: lambda a: a[::-1, ::-1],
        4: lambda a: a[::-1],
        5: lambda a: a.transpose(1, 0, 2),
        6: lambda a: a.transpose(1, 0, 2)[:, ::-1],
        7: lambda a: a.transpose(1, 0, 2)[::-1, ::-1],
        8: lambda a: a.transpose(1, 0, 2)[::-1],
    }
    transform = transforms.get(orientation)
    return rgb if transform is None else np.ascontiguousarray(transform(rgb))


def _rgb8_from_pil(pil: Image.Image, source: str) -> np.ndarray:
    """``(H, W, 3)`` uint8 RGB from a PIL image of any mode (orientation left as is)."""
    mode = pil.mode
    if mode in ("L", "LA", "RGB", "RGBA") or mode.startswith("I;16"):
        array = np.asarray(pil)
    elif mode == "I":
        # 32-bit integer images come from 16-bit grayscale files in some PIL versions.
        array = np.clip(np.asarray(pil), 0, 65535).astype(np.uint16)
    elif mode == "1":
        array = np.asarray(pil.convert("L"))
    elif mode in ("P", "PA"):
        transparent = mode == "PA" or "transparency" in pil.info
        array = np.asarray(pil.convert("RGBA" if transparent else "RGB"))
    elif mode in ("RGBa", "La"):
        array = np.asarray(pil.convert("RGBA"))
    elif mode == "F":
        raise ImageInputError(
            f"{source}: floating-point images are not supported; save the photo as an 8- or "
            "16-bit image"
        )
    else:
        array = np.asarray(pil.convert("RGB"))
    return _rgb8_from_array(array, source)


def _rgb8_from_array(array: np.ndarray, source: str) -> np.ndarray:
    """``(H, W, 3)`` uint8 RGB from a gray/gray+alpha/RGB/RGBA uint8 or uint16 array."""
    if array.dtype.byteorder not in ("=", "|"):
        array = array.astype(array.dtype.newbyteorder("="))
    if array.dtype not in (np.uint8, np.uint16):
        raise ImageInputError(
            f"{source}: pixel type {array.dtype} is not supported; pass uint8 (0-255) or uint16 "
            "(0-65535) pixels, e.g. (image * 255).round().astype(np.uint8) for floats in [0, 1]"
        )
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or array.shape[2] not in (1, 2, 3, 4):
        raise ImageInputError(
            f"{source}: expected an (H, W) grayscale or (H, W, C) image with C in 1-4 channels, "
            f"got shape {array.shape}"
        )
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ImageInputError(f"{source}: the image is empty (shape {array.shape})")
    channels = array.shape[2]
    colour = array[:, :, :3] if channels >= 3 else np.repeat(array[:, :, :1], 3, axis=2)
    if channels in (2, 4):
        return _composite_on_white(colour, array[:, :, -1])
    if array.dtype == np.uint16:
        return _uint16_to_uint8(colour)
    return np.ascontiguousarray(colour)


def _uint16_to_uint8(array: np.ndarray) -> np.ndarray:
    """``round(x * 255 / 65535)`` in integer arithmetic."""
    return ((array.astype(np.uint32) * 255 + 32767) // 65535).astype(np.uint8)


def _composite_on_white(colour: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``colour * a + white * (1 - a)``, rounded to uint8; works for uint8 and uint16 input."""
    full = float(np.iinfo(colour.dtype).max)
    weight = alpha.astype(np.float32)[:, :, None] / full
    blended = colour.astype(np.float32) * (255.0 / full) * weight + 255.0 * (1.0 - weight)
    return np.clip(np.rint(blended), 0, 255).astype(np.uint8)

"""The explorer's PNG export: the browser's render of the scene, cropped to what it shows and
captioned, so that a PNG put on a slide says what it is.

The browser renders the whole canvas (``client.get_render``), framed for the live app: room
for the floating panel on the right and empty space above and below the bodies, so most of it
is background (transparent: :func:`on_white` puts it on white). :func:`captioned_png` crops
the render to its content (every pixel that differs from the background, with a small
margin), writes the page caption (photo, person, evidence, boxes, samples, the posterior's
numbers: :meth:`hkpd.explorer.html_page.SceneCaption.text` without the page's "drag to
orbit") in a strip under it, and keeps the caption in the PNG's ``Description`` text chunk as
well.
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, ImageDraw, ImageFont
from PIL.PngImagePlugin import PngInfo

BACKGROUND_TOLERANCE = 12
"""A pixel differs from the background when a channel differs by more than this (0-255)."""
CONTENT_DIFFERENCE = 70
"""A grey pixel is content (for the crop) when it differs from the background by more than
this; the floor grid's lines differ by up to ~62 on a white background."""
CONTENT_CHROMA = 20
"""A pixel whose channels are this far apart is coloured: content even when light."""
MARGIN_FRACTION = 0.03
"""Margin kept around the content, as a fraction of the content's larger side."""
CAPTION_FONT_PX = 15
CAPTION_PADDING_PX = 12
CAPTION_INK = (34, 34, 34)
MIN_CAPTION_WIDTH_PX = 640
"""A crop narrower than this is widened (centred) so that the caption keeps readable lines."""


def on_white(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` uint8: an RGBA render composited over white (the browser renders the
    canvas background transparent, which most viewers show black or chequered), an RGB one
    as it is."""
    array = np.asarray(image)
    if array.shape[2] == 3:
        return array
    alpha = array[..., 3:].astype(np.float32) / 255.0
    mixed = array[..., :3].astype(np.float32) * alpha + 255.0 * (1.0 - alpha)
    return np.round(mixed).astype(np.uint8)


def background_colour(image: np.ndarray) -> np.ndarray:
    """``(3,)`` the most common colour of the render's four corners (the canvas background)."""
    corners = np.stack([image[0, 0], image[0, -1], image[-1, 0], image[-1, -1]])[:, :3]
    values, counts = np.unique(corners, axis=0, return_counts=True)
    return values[int(np.argmax(counts))]


def non_background_share(image: np.ndarray, background: np.ndarray | None = None) -> float:
    """Share of ``image``'s ``(H, W, 3|4)`` pixels that differ from ``background`` (default: its
    corners' colour) by more than :data:`BACKGROUND_TOLERANCE`."""
    rgb = np.asarray(image)[..., :3].astype(np.int16)
    colour = background_colour(image) if background is None else np.asarray(background)
    return float(np.mean(np.abs(rgb - colour.astype(np.int16)).max(axis=-1) > BACKGROUND_TOLERANCE))


def content_mask(image: np.ndarray) -> np.ndarray:
    """``(H, W)`` bool: the pixels of ``image`` ``(H, W, 3|4)`` that show something, i.e.
    differ from the background by more than :data:`CONTENT_DIFFERENCE` or are coloured
    (channels :data:`CONTENT_CHROMA` apart); the floor grid's faint grey lines, which run the
    whole width of the canvas, are not content."""
    rgb = np.asarray(image)[..., :3].astype(np.int16)
    differs = np.abs(rgb - background_colour(image).astype(np.int16)).max(axis=-1)
    chroma = rgb.max(axis=-1) - rgb.min(axis=-1)
    return (differs > CONTENT_DIFFERENCE) | (
        (differs > BACKGROUND_TOLERANCE) & (chroma > CONTENT_CHROMA)
    )


def content_crop(image: np.ndarray) -> np.ndarray:
    """``image`` ``(H, W, 3|4)`` uint8 cropped to its :func:`content_mask`, with a
    :data:`MARGIN_FRACTION` margin (the whole image when nothing shows)."""
    rgb = np.asarray(image)[..., :3]
    mask = content_mask(image)
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return np.asarray(image)
    margin = round(MARGIN_FRACTION * max(rows[-1] - rows[0], cols[-1] - cols[0]))
    height, width = rgb.shape[:2]
    y0, y1 = max(rows[0] - margin, 0), min(rows[-1] + 1 + margin, height)
    x0, x1 = max(cols[0] - margin, 0), min(cols[-1] + 1 + margin, width)
    if x1 - x0 < MIN_CAPTION_WIDTH_PX:  # widen around the centre, within the render
        span = min(MIN_CAPTION_WIDTH_PX, width)
        x0 = int(np.clip((x0 + x1 - span) // 2, 0, width - span))
        x1 = x0 + span
    return np.asarray(image)[y0:y1, x0:x1]


def wrap_lines(text: str, width_px: int, font: ImageFont.FreeTypeFont) -> list[str]:
    """``text`` broken at spaces into lines at most ``width_px`` wide in ``font``."""
    lines: list[str] = []
    for word in text.split():
        if lines and font.getlength(f"{lines[-1]} {word}") <= width_px:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines


def caption_strip(text: str, width: int, background: np.ndarray) -> np.ndarray:
    """``(h, width, 3)`` uint8: ``text`` wrapped in dark ink on ``background``."""
    font = ImageFont.load_default(size=CAPTION_FONT_PX)
    lines = wrap_lines(text, width - 2 * CAPTION_PADDING_PX, font)
    line_height = round(CAPTION_FONT_PX * 1.35)
    height = 2 * CAPTION_PADDING_PX + line_height * len(lines)
    strip = Image.new("RGB", (width, height), tuple(int(c) for c in background[:3]))
    draw = ImageDraw.Draw(strip)
    for index, line in enumerate(lines):
        position = (CAPTION_PADDING_PX, CAPTION_PADDING_PX + index * line_height)
        draw.text(position, line, fill=CAPTION_INK, font=font)
    return np.asarray(strip)


def captioned_image(render: np.ndarray, caption: str) -> np.ndarray:
    """``(H', W', 3)`` uint8: ``render`` ``(H, W, 3|4)`` cropped to its content, with
    ``caption`` written under it (see the module docstring)."""
    array = np.asarray(render)
    if array.ndim != 3 or array.shape[2] not in (3, 4) or array.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3|4) uint8 render, got {array.shape} {array.dtype}")
    flat = on_white(array)
    cropped = content_crop(flat)
    if not caption.strip():
        return np.ascontiguousarray(cropped)
    strip = caption_strip(caption, cropped.shape[1], background_colour(flat))
    return np.concatenate([cropped, strip], axis=0)


def captioned_png(render: np.ndarray, caption: str) -> bytes:
    """PNG file bytes of :func:`captioned_image`; the caption is also the PNG's
    ``Description`` text chunk (and ``Software``: hkpd explorer)."""
    info = PngInfo()
    info.add_text("Description", caption)
    info.add_text("Software", "hkpd explorer")
    buffer = io.BytesIO()
    Image.fromarray(captioned_image(render, caption)).save(buffer, format="PNG", pnginfo=info)
    return buffer.getvalue()

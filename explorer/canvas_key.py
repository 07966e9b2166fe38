"""The key drawn in the 3D view, under the photo: what the dots, lines, boxes and body colours
mean, and what the uncertainty body's colours show under the current colouring (the colour
bar under that body gives the numbers). It is an image in the scene, so it is in the view, in
screenshots and in saved pages, not only in the panel; the app redraws it when the colouring
changes.
"""

from __future__ import annotations

import threading

import cv2
import numpy as np
import viser

from hkpd.explorer.colour_map import (
    CHANGE_MAX_RATIO,
    COLOURINGS,
    LOG_BOTTOM_CM,
    LOG_TOP_CM,
    HeatmapScale,
)
from hkpd.explorer.photo_geometry import HALF_TURN_ABOUT_X, PhotoPlacement
from hkpd.explorer.scene import FLOOR_HEIGHT, LEGEND_Z

KEY_SIZE_PX = (880, 1280)
"""``(height, width)`` of the key image, pixels (large: it is read at a distance)."""
TEXT_SIZE = 1.7
"""Hershey font scale of the rows' text."""
SENT_SCALE = 0.4
"""The key is drawn large and sent at this scale (512 x 352 pixels, ~80 kB of PNG: it is read
at about that size, and every saved page carries it)."""
KEY_WIDTH_M = 1.5
"""World width of the key; its height follows the image's aspect."""
KEY_GAP_M = 0.1
"""World gap between the photo's bottom (or the floor, when lower) and the key's top."""
KEY_NODE = "/key"
SYMBOL_X, TEXT_LEFT = 80, 160
"""Pixel column of the rows' symbols' centres and of their text's start."""
INK = (40, 40, 40)

_Row = tuple[str, str, tuple[int, int, int]]
"""A row: the symbol's kind, its text, its colour (RGB)."""

DRAWING_ROWS: tuple[_Row, ...] = (
    ("dot", "keypoint: evidence", (40, 220, 90)),
    ("dot", "keypoint: not evidence", (235, 50, 50)),
    ("line", "samples, in 2D (fan out: unsure)", (90, 150, 235)),
    ("line", "most likely body, in 2D", (255, 140, 30)),
    ("box", "box: hidden, no evidence", (250, 200, 40)),
    ("frame", "person box", (40, 200, 255)),
    ("square", "hand/foot mark (hollow: unused)", (40, 170, 255)),
    ("swatch", "most likely body; samples", (90, 150, 235)),
)
"""The photo's and the middle column's drawings (colours as :mod:`hkpd.explorer.scene`
draws them)."""

COLOURING_LINES = {
    "log": "right: uncertainty, cm (log)",
    "linear": "right: uncertainty, cm (linear)",
    "change": "right: red less, blue more sure",
}
"""The last row, by colouring (:data:`~hkpd.explorer.colour_map.COLOURINGS`)."""


def key_image(colouring: str = "log") -> np.ndarray:
    """The key as ``(300, 640, 3)`` uint8 RGB on white: one row per drawing, then one for the
    uncertainty body's colouring.

    Raises:
        ValueError: an unknown colouring.
    """
    if colouring not in COLOURINGS:
        raise ValueError(f"unknown colouring {colouring!r}; use one of {list(COLOURINGS)}")
    height, width = KEY_SIZE_PX
    image = np.full((height, width, 3), 255, dtype=np.uint8)
    _text(image, "Key", (TEXT_LEFT - 120, 64), TEXT_SIZE * 1.1, 4)
    rows = (*DRAWING_ROWS, ("ramp", COLOURING_LINES[colouring], INK))
    pitch = (height - 90) // len(rows)
    for index, (kind, text, colour) in enumerate(rows):
        centre_y = 90 + pitch * index + pitch // 2
        _symbol(image, kind, colour, (SYMBOL_X, centre_y), colouring)
        _text(image, text, (TEXT_LEFT, centre_y + 18), TEXT_SIZE, 3)
    cv2.rectangle(image, (0, 0), (width - 1, height - 1), (170, 170, 170), 4)
    return image


def _symbol(image: np.ndarray, kind: str, colour, centre: tuple[int, int], colouring: str):
    """One row's symbol, about 90 x 44 pixels around ``centre``."""
    x, y = centre
    rgb = tuple(int(c) for c in colour)  # the image is RGB: cv2 writes the tuple as given
    if kind == "dot":
        cv2.circle(image, centre, 18, rgb, -1, cv2.LINE_AA)
    elif kind == "line":
        cv2.line(image, (x - 45, y), (x + 45, y), rgb, 8, cv2.LINE_AA)
    elif kind == "box":
        cv2.rectangle(image, (x - 40, y - 22), (x + 40, y + 22), (15, 15, 20), -1)
        cv2.rectangle(image, (x - 40, y - 22), (x + 40, y + 22), rgb, 5)
    elif kind == "frame":
        cv2.rectangle(image, (x - 40, y - 22), (x + 40, y + 22), rgb, 7)
    elif kind == "square":
        cv2.rectangle(image, (x - 44, y - 14), (x - 16, y + 14), rgb, -1)
        cv2.rectangle(image, (x + 16, y - 14), (x + 44, y + 14), rgb, 5)
    elif kind == "swatch":
        cv2.rectangle(image, (x - 45, y - 22), (x - 4, y + 22), (200, 194, 186), -1)
        cv2.rectangle(image, (x + 4, y - 22), (x + 45, y + 22), rgb, -1)
    else:  # the colouring's ramp, in miniature
        image[y - 16 : y + 16, x - 45 : x + 45] = ramp_strip(colouring, 90)[None]


def key_rect(placement: PhotoPlacement) -> tuple[float, float, float, float]:
    """Where the key goes, ``(centre x, centre y, width, height)`` in world metres: under the
    photo (and under the floor line when the photo ends above it), as wide as
    :data:`KEY_WIDTH_M`."""
    height_px, width_px = KEY_SIZE_PX
    height = KEY_WIDTH_M * height_px / width_px
    bottom_of_photo = placement.centre[1] - placement.height_m / 2
    top = min(bottom_of_photo, FLOOR_HEIGHT) - KEY_GAP_M
    return placement.centre[0], top - height / 2, KEY_WIDTH_M, height


class CanvasKey:
    """The key in a viser scene, under the photo; redrawn for a new photo or colouring.

    Args:
        server: the ``viser.ViserServer``.
    """

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.colouring = "log"
        self.placement: PhotoPlacement | None = None
        self._lock = threading.Lock()

    def show(self, placement: PhotoPlacement | None = None, colouring: str | None = None) -> None:
        """Draw the key under ``placement``'s photo (None: the last one) for ``colouring``
        (None: the last one); nothing before a photo is placed."""
        with self._lock:
            self.placement = placement or self.placement
            self.colouring = colouring or self.colouring
            if self.placement is None:
                return
            x, y, width, height = key_rect(self.placement)
            image = cv2.resize(key_image(self.colouring), None, fx=SENT_SCALE, fy=SENT_SCALE,
                               interpolation=cv2.INTER_AREA)  # fmt: skip
            self.server.scene.add_image(
                KEY_NODE, image, width, height, format="png",
                wxyz=HALF_TURN_ABOUT_X, position=(x, y, LEGEND_Z), cast_shadow=False,
                receive_shadow=False,
            )  # fmt: skip


def ramp_strip(colouring: str, width: int) -> np.ndarray:
    """``(width, 3)`` uint8: the colouring's colours from its low end to its high end."""
    scale = HeatmapScale(colouring)
    if colouring == "change":
        values = np.geomspace(1 / CHANGE_MAX_RATIO, CHANGE_MAX_RATIO, width)  # ratios
    elif colouring == "log":
        values = np.geomspace(LOG_BOTTOM_CM, LOG_TOP_CM, width) / 100.0  # metres
    else:
        values = np.linspace(0.0, scale.max_cm, width) / 100.0
    return scale.colours(values)


def _text(image: np.ndarray, text: str, origin: tuple[int, int], size: float, thick: int):
    """Hershey fonts have no "×" or "÷": ASCII stand-ins."""
    ascii_text = text.replace("×", "x").replace("÷", "/")
    cv2.putText(image, ascii_text, origin, cv2.FONT_HERSHEY_SIMPLEX, size, INK, thick,
                cv2.LINE_AA)  # fmt: skip

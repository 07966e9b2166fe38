"""Where the explorer's camera stands: the photo, the bodies, the colour bar and the key framed
for a canvas of a given aspect, left of the floating control panel.

The drawings are a row (photo, most likely body + samples, uncertainty body; optionally the
combined-shape body and the compare columns) that is wider than the canvas left of the panel
is tall, so the framing is usually limited by width: it fits the row's real right end (the
uncertainty body's reach, from the mode's keypoints, instead of a fixed arm span) and puts the
key under the photo, in the band below the bodies that was empty. The columns themselves are
spaced by the person's reach (:mod:`hkpd.explorer.layout`), which narrows the row.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

from hkpd.explorer.canvas_key import key_rect
from hkpd.explorer.layout import (
    BODY_HALF_SPAN_M,
    DEFAULT_LAYOUT,
    HAND_ROOM_M,
    MIN_REACH_M,
    ColumnLayout,
    body_extent,
)
from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.scene import LEGEND_HEIGHT, LEGEND_SIZE_M

CAMERA_FOV_DEG = 40.0
ASSUMED_ASPECT = 1.6
"""Canvas width / height the first view is framed for (a laptop browser window)."""
FREE_CANVAS_FRACTION = 0.7
"""Part of the canvas width not covered by the floating control panel (before a tab reports
its canvas size)."""
PANEL_WIDTH_PX = 420
"""Width of viser's floating panel ("large" controls) plus its margin, CSS pixels."""
__all__ = ["BODY_HALF_SPAN_M", "HAND_ROOM_M", "MIN_REACH_M", "body_reach", "framing"]
PAGE_ASPECT = 1.25
"""Canvas width / height a saved page is framed for: narrower than a laptop window, so that a
page opened in a 4:3 or 5:4 window still shows the whole row (framed for 1.6 with room for the
panel, a 1024 x 768 window cut the photo off at the left)."""
PAGE_CAPTION_ROOM = 0.36
"""Share of a saved page's height kept free at the bottom for its caption box (at most 32 % of
the window tall, :data:`hkpd.explorer.html_page.CAPTION_STYLE`), which covered the key."""
TITLE_ROOM_M = 0.25
"""Room above the photo's top (or 1 m) for the column titles."""
MARGIN_M = 0.2


def body_reach(result: object) -> float:
    """Metres right of the body's centre its drawing reaches: the mode's rightmost keypoint
    plus :data:`HAND_ROOM_M`, within [:data:`MIN_REACH_M`, :data:`BODY_HALF_SPAN_M`];
    :data:`BODY_HALF_SPAN_M` when ``result`` (a ``PredictionResult``) is None or has no
    keypoints (a custom provider's). The right half of :func:`~hkpd.explorer.layout.body_extent`;
    the combined-shape body (a T-pose) always gets :data:`BODY_HALF_SPAN_M`."""
    return body_extent(result)[1]


def framing(
    placement: PhotoPlacement,
    aspect: float,
    free_fraction: float = FREE_CANVAS_FRACTION,
    combined: bool = False,
    compare: bool = False,
    reach: float = BODY_HALF_SPAN_M,
    layout: ColumnLayout = DEFAULT_LAYOUT,
    bottom_room: float = 0.0,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Camera ``(position, look_at)`` showing photo, key, bodies and colour bars left of the
    panel.

    Args:
        placement: where the photo is.
        aspect: canvas width / height.
        free_fraction: part of the canvas width left of the floating panel.
        combined: also show the combined-shape body of the same person's photos.
        compare: also show the compare columns (B).
        reach: metres right of the uncertainty body's centre its drawing reaches
            (:func:`body_reach`).
        layout: where the columns stand (the scene's :attr:`ExplorerScene.layout`).
        bottom_room: share of the canvas height kept free under the drawings (a saved
            page's caption box, :data:`PAGE_CAPTION_ROOM`).
    """
    key_x, key_y, key_width, key_height = key_rect(placement)
    left = min(placement.centre[0] - placement.width_m / 2, key_x - key_width / 2) - MARGIN_M
    right = layout.heat_x + max(reach, LEGEND_SIZE_M[0] / 2)
    if combined:
        right = layout.combined_x + BODY_HALF_SPAN_M
    if compare:
        right = max(right, layout.compare_heat_x + max(reach, LEGEND_SIZE_M[0] / 2))
    top = max(placement.centre[1] + placement.height_m / 2, 1.0) + TITLE_ROOM_M
    bar_bottom = LEGEND_HEIGHT - LEGEND_SIZE_M[1] / 2
    bottom = min(key_y - key_height / 2, bar_bottom) - MARGIN_M
    tan_v = math.tan(math.radians(CAMERA_FOV_DEG) / 2)
    tan_h = tan_v * aspect
    # The content should fill the part of the canvas that the floating panel leaves free.
    visible_width = (right - left) / free_fraction
    distance = max(visible_width / (2 * tan_h), (top - bottom) / ((1 - bottom_room) * 2 * tan_v))
    shift = (0.5 - free_fraction / 2) * 2 * distance * tan_h
    centre = ((left + right) / 2 + shift, (top + bottom) / 2 - bottom_room * distance * tan_v)
    return (centre[0], centre[1] + 0.1, distance), (centre[0], centre[1], 0.0)


@contextlib.contextmanager
def page_camera(initial_camera, placement: PhotoPlacement, **row: object) -> Iterator[None]:
    """Inside: ``initial_camera`` (``server.initial_camera``, what a saved page opens with)
    framed for a page: no control panel (the whole width), :data:`PAGE_ASPECT`, the bottom
    :data:`PAGE_CAPTION_ROOM` left to the caption; after: as it was.

    Args:
        initial_camera: has ``position`` and ``look_at``.
        placement: where the photo is.
        row: :func:`framing`'s ``combined``, ``compare``, ``reach`` and ``layout``.
    """
    before = (initial_camera.position, initial_camera.look_at)
    framed = framing(placement, PAGE_ASPECT, 1.0, bottom_room=PAGE_CAPTION_ROOM, **row)  # type: ignore[arg-type]
    position, look_at = framed
    initial_camera.position, initial_camera.look_at = position, look_at
    try:
        yield
    finally:
        initial_camera.position, initial_camera.look_at = before

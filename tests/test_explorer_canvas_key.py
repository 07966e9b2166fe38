"""The key drawn in the 3D view (explorer/canvas_key.py) and the framing that fits the bodies'
real reach and the key (explorer/framing.py)."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import torch

from hkpd.explorer.canvas_key import (
    COLOURING_LINES,
    DRAWING_ROWS,
    KEY_NODE,
    KEY_SIZE_PX,
    TEXT_LEFT,
    TEXT_SIZE,
    key_image,
    key_rect,
)
from hkpd.explorer.colour_map import COLOURINGS
from hkpd.explorer.framing import (
    BODY_HALF_SPAN_M,
    HAND_ROOM_M,
    MIN_REACH_M,
    body_reach,
    framing,
)
from hkpd.explorer.photo_geometry import PhotoPlacement

PLACEMENT = PhotoPlacement(480, 640, (-1.65, 0.0, 0.0), 2.0)


def test_every_row_of_the_key_fits_and_the_colouring_row_follows_the_colouring() -> None:
    height, width = KEY_SIZE_PX
    texts = [text for _kind, text, _colour in DRAWING_ROWS] + list(COLOURING_LINES.values())
    for text in texts:
        (text_width, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, TEXT_SIZE, 3)
        assert TEXT_LEFT + text_width < width, text
    images = {kind: key_image(kind) for kind in COLOURINGS}
    assert all(image.shape == (height, width, 3) for image in images.values())
    # The drawing rows are the same; the last row (the colouring's words and ramp) is not.
    top = slice(0, height - 100)
    assert np.array_equal(images["log"][top], images["change"][top])
    assert not np.array_equal(images["log"][-100:], images["change"][-100:])
    # The keypoint dots are drawn in the scene's colours.
    assert (images["log"] == (40, 220, 90)).all(axis=2).sum() > 500
    with pytest.raises(ValueError, match="unknown colouring"):
        key_image("rainbow")


def test_the_key_sits_under_the_photo_and_inside_the_framing() -> None:
    x, y, _width, height = key_rect(PLACEMENT)
    assert x == PLACEMENT.centre[0] and y + height / 2 < PLACEMENT.centre[1] - 1.0
    (_x, cy, distance), _ = framing(PLACEMENT, 1.6, 1.0)
    tan_v = np.tan(np.radians(20.0))
    assert cy - 0.1 - distance * tan_v <= y - height / 2  # the key's bottom is in view


def posed(right_wrist_x: float):
    points = torch.zeros(1, 17, 3, dtype=torch.float64)
    points[0, 10, 0] = right_wrist_x
    mode = SimpleNamespace(keypoints3d=points)
    return SimpleNamespace(posterior=SimpleNamespace(mode=lambda: mode))


def test_the_framing_fits_the_bodies_reach() -> None:
    assert body_reach(None) == BODY_HALF_SPAN_M  # unknown: room for outstretched arms
    assert body_reach(posed(0.3)) == pytest.approx(0.3 + HAND_ROOM_M)
    assert body_reach(posed(0.05)) == MIN_REACH_M
    assert body_reach(posed(2.0)) == BODY_HALF_SPAN_M
    (_, _, arms_down), _ = framing(PLACEMENT, 1.56, 0.7, reach=body_reach(posed(0.3)))
    (_, _, arms_out), _ = framing(PLACEMENT, 1.56, 0.7)
    assert arms_down < 0.96 * arms_out  # closer (the colour bar, 1.4 m wide, limits it)


def test_the_app_draws_the_key_and_redraws_it_with_the_colouring() -> None:
    from test_explorer_double import OcclusionAwareDouble

    from hkpd.explorer.app import ExplorerApp

    double = OcclusionAwareDouble()
    app = ExplorerApp(double, double.scene.image, port=0, num_samples=20, num_displayed=2)
    try:
        assert app.wait_idle(60)
        nodes = app.server.scene._handle_from_node_name
        assert KEY_NODE in nodes and app.key.colouring == "log"
        first = nodes[KEY_NODE]
        app.panels.samples.colouring.value = COLOURINGS["change"]
        assert app.wait_idle(60)
        assert app.key.colouring == "change" and nodes[KEY_NODE] is not first
        assert app.key.placement == app.scene.placement
    finally:
        app.stop()

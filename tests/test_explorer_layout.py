"""The explorer's columns spaced by the person's reach (explorer/layout.py): a person with the
arms down gets a narrower row, so the framing draws the bodies larger, and everything (photo,
key, both bodies, B's columns) still fits left of the control panel."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from test_explorer_double import OcclusionAwareDouble

from hkpd.explorer.canvas_key import key_rect
from hkpd.explorer.framing import CAMERA_FOV_DEG, body_reach, framing
from hkpd.explorer.layout import (
    BODY_HALF_SPAN_M,
    COLUMN_GAP_M,
    DEFAULT_LAYOUT,
    HAND_ROOM_M,
    ColumnLayout,
    body_extent,
    column_layout,
)
from hkpd.explorer.photo_geometry import PhotoPlacement
from hkpd.explorer.scene import COMBINED_OFFSET, HEATMAP_OFFSET, PHOTO_GAP

WINDOW = (1400, 900)
PANEL_PX = 420


def posed(left_x: float, right_x: float):
    """A result whose mode has its leftmost keypoint at ``left_x`` and rightmost at ``right_x``."""
    points = torch.zeros(1, 17, 3, dtype=torch.float64)
    points[0, 9, 0], points[0, 10, 0] = left_x, right_x
    mode = SimpleNamespace(keypoints3d=points)
    return SimpleNamespace(posterior=SimpleNamespace(mode=lambda: mode))


def pixels_per_metre(distance: float, height_px: int = WINDOW[1]) -> float:
    """Canvas pixels per metre on the photo plane (z = 0) seen from ``distance``."""
    return height_px / (2 * distance * math.tan(math.radians(CAMERA_FOV_DEG) / 2))


def visible_x(
    camera: tuple[float, float, float], aspect: float, free: float
) -> tuple[float, float]:
    """World x range on z = 0 that is on the canvas and left of the panel."""
    x, _, distance = camera
    half = distance * math.tan(math.radians(CAMERA_FOV_DEG) / 2) * aspect
    return x - half, x - half + 2 * half * free


def test_the_default_layout_is_the_old_fixed_spacing() -> None:
    assert (DEFAULT_LAYOUT.photo_gap, DEFAULT_LAYOUT.heat_x) == (PHOTO_GAP, HEATMAP_OFFSET)
    assert DEFAULT_LAYOUT.combined_x == COMBINED_OFFSET == pytest.approx(3.65)
    assert DEFAULT_LAYOUT.compare_body_x == pytest.approx(3.65)
    assert DEFAULT_LAYOUT.compare_heat_x == pytest.approx(5.4)
    with pytest.raises(ValueError, match="positive gaps"):
        ColumnLayout(photo_gap=0.5, step=-1.0)
    with pytest.raises(ValueError, match="finite"):
        ColumnLayout(photo_gap=math.nan)


def test_arms_down_narrows_the_row_and_draws_the_bodies_larger() -> None:
    assert body_extent(None) == (BODY_HALF_SPAN_M, BODY_HALF_SPAN_M)
    assert column_layout(None) == DEFAULT_LAYOUT  # unknown reach: room for outstretched arms
    assert column_layout(posed(-0.9, 0.9)) == DEFAULT_LAYOUT  # never wider than the default
    down = column_layout(posed(-0.3, 0.35))
    assert down.step == pytest.approx(0.3 + 0.35 + 2 * HAND_ROOM_M + COLUMN_GAP_M)
    assert down.photo_gap == pytest.approx(0.3 + HAND_ROOM_M + COLUMN_GAP_M)
    # The demo photo's size (portrait), its right edge at each layout's photo gap.
    placements = {
        layout: PhotoPlacement(384, 512, (-(layout.photo_gap + 0.89), 0.1, 0.0), 2.37)
        for layout in (DEFAULT_LAYOUT, down)
    }
    aspect, free = WINDOW[0] / WINDOW[1], 1 - PANEL_PX / WINDOW[0]
    reach = body_reach(posed(-0.3, 0.35))
    scale = {
        layout: pixels_per_metre(framing(placement, aspect, free, reach=reach, layout=layout)[0][2])
        for layout, placement in placements.items()
    }
    assert scale[down] > 1.12 * scale[DEFAULT_LAYOUT]  # the bodies drawn >= 12 % taller


@pytest.fixture(scope="module")
def app():
    from hkpd.explorer.app import ExplorerApp

    double = OcclusionAwareDouble()
    explorer = ExplorerApp(double, double.scene.image, port=0, num_samples=20, num_displayed=3)
    assert explorer.wait_idle(60)
    yield explorer
    explorer.stop()


def test_the_app_spaces_the_columns_by_the_persons_reach(app) -> None:
    layout = app.scene.layout
    assert layout == column_layout(app.result) and layout.step < 0.8 * DEFAULT_LAYOUT.step
    nodes = app.server.scene._handle_from_node_name
    for name in ("/heat", "/titles/uncertainty", "/legend"):
        assert nodes[name].position[0] == pytest.approx(layout.heat_x), name
    placement = app.scene.placement
    assert placement.centre[0] + placement.width_m / 2 == pytest.approx(-layout.photo_gap)
    # The bodies do not touch: the most likely body (and its samples) ends left of where the
    # uncertainty body begins, and right of the photo.
    view = app.view
    drawn = np.concatenate([view.mode_vertices[None], view.sample_vertices])[..., 0]
    assert drawn.max() + 0.1 < layout.heat_x + view.mode_vertices[:, 0].min()
    assert drawn.min() > -layout.photo_gap


def test_compare_columns_follow_the_layout_and_everything_fits(app) -> None:
    app.panels.compare.menu.value = "B: without the boxes"  # what a click in the menu does
    assert app.wait_idle(60) and app.compare_columns.shown
    layout, view = app.scene.layout, app.view
    nodes = app.server.scene._handle_from_node_name
    assert nodes["/compare_body"].position[0] == pytest.approx(layout.compare_body_x)
    assert nodes["/compare_heat"].position[0] == pytest.approx(layout.compare_heat_x)
    assert nodes["/compare_legend"].position[0] == pytest.approx(layout.compare_heat_x)
    x = view.mode_vertices[:, 0]
    assert layout.heat_x + x.max() + 0.1 < layout.compare_body_x + x.min()  # A's and B's apart
    # At 1400 x 900, 1920 x 1080 and a 1280 x 720 projector: from the photo's left edge (and the
    # key's) to B's colour bar, left of the panel.
    placement, reach = app.scene.placement, body_reach(app.result)
    left = min(placement.centre[0] - placement.width_m / 2, key_rect(placement)[0] - 0.75)
    right = layout.compare_heat_x + max(x.max(), 0.7)
    for width, height in (WINDOW, (1920, 1080), (1280, 720)):
        aspect, free = width / height, 1 - PANEL_PX / width
        camera, _ = framing(placement, aspect, free, compare=True, reach=reach, layout=layout)
        seen_left, seen_right = visible_x(camera, aspect, free)
        assert seen_left < left and right <= seen_right + 1e-9, (width, height)
    app.panels.compare.menu.value = "Off"
    assert app.wait_idle(60) and not app.compare_columns.shown


def test_set_layout_moves_the_drawn_columns(app) -> None:
    old = app.scene.layout
    try:
        app.scene.set_layout(DEFAULT_LAYOUT)
        nodes = app.server.scene._handle_from_node_name
        assert nodes["/heat"].position[0] == pytest.approx(HEATMAP_OFFSET)
        assert nodes["/titles/uncertainty"].position[0] == pytest.approx(HEATMAP_OFFSET)
        assert nodes["/legend"].position[0] == pytest.approx(HEATMAP_OFFSET)
    finally:
        app.scene.set_layout(old)


def test_nothing_drawn_over_the_photo_spills_past_its_edges(app) -> None:
    """Issue 58: keypoints, hand/foot marks and the fitted body were drawn below the photo's
    bottom edge when the detector placed them (or the crop box reached) past it."""
    scene, placement = app.scene, app.scene.placement
    nodes = app.server.scene._handle_from_node_name
    width, height = placement.width_px, placement.height_px
    half_w, half_h = placement.width_m / 2, placement.height_m / 2
    keypoints = np.tile([[width / 2, height / 2]], (17, 1)).astype(float)
    keypoints[15:] = [[width * 0.4, height + 40], [width * 0.6, height + 90]]  # ankles below
    try:
        scene.show_keypoints(keypoints, np.ones(17))
        drawn = nodes["/photo/keypoints"].points
        assert len(drawn) == 15 and (np.abs(drawn[:, :2]) <= [half_w, half_h]).all()
        rgba = np.full((256, 256, 4), 200, np.uint8)
        box = (width * 0.3, height * 0.5, width * 0.3 + height, height * 1.5)  # half below
        scene.show_fit_overlay(rgba, box)
        fit = nodes["/photo/fit"]
        assert fit.render_height == pytest.approx(half_h, rel=0.02)  # the upper half only
        assert fit.position[1] + fit.render_height / 2 <= half_h + 1e-6
        assert fit.position[1] - fit.render_height / 2 >= 0.0 - 1e-6
        landmarks = SimpleNamespace(
            network_input=SimpleNamespace(detection=SimpleNamespace(extremities=np.array(
                [[width * 0.5, height * 0.5], [width * 0.5, height + 30.0]]
            )), extremity_evidence=np.array([True, True])),
        )  # fmt: skip
        app.landmark_marks.show(landmarks)
        assert len(nodes["/photo/landmarks/evidence"].points) == 1
    finally:
        app.show_fit(True, 0.55)
        app.scene.show_keypoints(
            app.result.posterior.keypoints.numpy(), app.result.posterior.confidences.numpy()
        )
        app.landmark_marks.show(app.result.posterior)


def test_a_saved_page_frames_everything_above_its_caption(app) -> None:
    """Issue 58: an exported compare page was framed as the live app (room for a control panel
    the page does not have, a 1.6 window): a 1024 x 768 window cut the photo off at the left,
    and the caption box covered the key. The page's camera fits the whole row, key and colour
    bars included, in a 5:4 window's upper part, above the caption's band."""
    from hkpd.explorer.framing import PAGE_ASPECT, PAGE_CAPTION_ROOM, TITLE_ROOM_M, page_camera
    from hkpd.explorer.scene import LEGEND_HEIGHT

    placement, layout, reach = app.scene.placement, app.scene.layout, body_reach(app.result)
    camera = SimpleNamespace(position=(1.0, 2.0, 3.0), look_at=(0.0, 0.0, 0.0))
    with page_camera(camera, placement, compare=True, reach=reach, layout=layout):
        (x, _, distance), look_at = camera.position, camera.look_at
    assert camera.position == (1.0, 2.0, 3.0)  # restored after the page
    key_x, key_y, key_w, key_h = key_rect(placement)
    left = min(placement.centre[0] - placement.width_m / 2, key_x - key_w / 2)
    right = layout.compare_heat_x + reach
    bottom = min(key_y - key_h / 2, LEGEND_HEIGHT - 0.1)
    top = max(placement.centre[1] + placement.height_m / 2, 1.0) + TITLE_ROOM_M
    half_v = distance * math.tan(math.radians(CAMERA_FOV_DEG) / 2)
    for aspect in (PAGE_ASPECT, 4 / 3, 16 / 10, 16 / 9):
        assert x - half_v * aspect <= left and right <= x + half_v * aspect, aspect
    caption_top = look_at[1] - half_v + 2 * half_v * PAGE_CAPTION_ROOM
    assert bottom >= caption_top - 1e-9 and top <= look_at[1] + half_v + 1e-9

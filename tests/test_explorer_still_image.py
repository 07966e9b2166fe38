"""The PNG export (issue 50): the browser's render cropped to the scene and captioned, so that
a PNG on a slide says what it shows and is not mostly background."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from hkpd.explorer.html_page import SceneCaption
from hkpd.explorer.still_image import (
    captioned_image,
    captioned_png,
    content_crop,
    non_background_share,
    on_white,
)

CAPTION = SceneCaption(
    photo="warrior_lunge.jpg", model="the shipped model", evidence="Conditioned on 17 keypoints.",
    occluders=((385.0, 364.0, 465.0, 584.0),), num_samples=100, num_displayed=10,
    numbers="Mean vertex uncertainty: whole body 9.1 cm; right shin 13.9 cm.",
)  # fmt: skip


def render_like_the_app() -> np.ndarray:
    """A 720 x 1280 RGBA render as the browser sends it for the live app's framing: a
    transparent canvas, the photo and three body columns in a band in the left part (room for
    the panel on the right)."""
    image = np.zeros((720, 1280, 4), np.uint8)
    rng = np.random.default_rng(0)
    image[250:470, 60:230, :3] = rng.integers(0, 200, (220, 170, 3))  # the photo
    for x in (300, 470, 640):  # mode + samples, uncertainty body, B
        image[240:480, x : x + 90, :3] = (120, 140, 200)
    image[240:480, 60:730, 3] = 255
    return image


def test_the_png_is_cropped_to_the_scene_and_says_what_it_shows() -> None:
    render = render_like_the_app()
    text = CAPTION.text(interactive=False)
    assert "Drag to orbit" not in text and "Drag to orbit" in CAPTION.text()
    png = captioned_png(render, text)
    still = Image.open(io.BytesIO(png))
    assert still.text["Description"] == text  # the caption travels with the file
    pixels = np.asarray(still.convert("RGB"))
    assert (pixels[0, 0] == 255).all()  # the transparent canvas comes out white
    before, after = non_background_share(on_white(render)), non_background_share(pixels)
    assert before < 0.2 and after > 0.5, (before, after)  # measured: 0.17 -> 0.61
    scene_rows = content_crop(on_white(render)).shape[0]
    strip = pixels[scene_rows:]
    assert strip.shape[0] > 30 and non_background_share(strip) > 0.02  # the caption is drawn
    assert pixels.shape[1] < render.shape[1] and pixels.shape[0] < render.shape[0] + 200


def test_a_blank_or_narrow_render_and_bad_input() -> None:
    blank = np.full((100, 200, 3), 255, np.uint8)
    assert captioned_image(blank, "").shape == (100, 200, 3)  # nothing to crop, no caption
    narrow = np.full((400, 1280, 3), 255, np.uint8)
    narrow[100:300, 600:640] = 0
    assert captioned_image(narrow, "A caption.").shape[1] == 640  # widened for the caption
    with pytest.raises(ValueError, match="uint8 render"):
        captioned_png(np.zeros((10, 10), np.uint8), "x")

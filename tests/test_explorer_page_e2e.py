"""The exported page in a real headless Chromium, from file:// with the network off: it draws
the 3D scene (a WebGL canvas showing the photo and the bodies) and asks for nothing outside the
file. Skipped like ``test_explorer_e2e.py`` when playwright or /usr/bin/chromium is missing."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image
from test_explorer_e2e import CANVAS_SHOWN, VIEWPORT, launch_chromium, playwright_api

from hkpd.explorer import cli
from hkpd.explorer.html_page import CAPTION_ID
from hkpd.explorer.scene import MODE_COLOUR

LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:")


def test_exported_page_draws_the_scene_offline_from_a_file(tmp_path) -> None:
    page_path = tmp_path / "page.html"
    assert cli.main([
        "--demo", "synthetic", "--provider", "test_explorer_double:OcclusionAwareDouble",
        "--meshes", "2", "--export-html", str(page_path), "--occluder", "250", "210", "300", "260",
    ]) == 0  # fmt: skip
    outside: list[str] = []
    with playwright_api.sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        context = browser.new_context(viewport=VIEWPORT)
        context.set_offline(True)

        def refuse_outside(route) -> None:
            if route.request.url.startswith(LOCAL_SCHEMES):
                route.continue_()
            else:
                outside.append(route.request.url)
                route.abort()

        context.route("**/*", refuse_outside)
        page = context.new_page()
        page.goto(page_path.as_uri())
        page.wait_for_function(CANVAS_SHOWN, timeout=60_000)
        page.wait_for_timeout(4000)  # the embedded scene decodes, then WebGL draws
        caption = page.locator(f"#{CAPTION_ID}")
        assert caption.is_visible() and "1 occluder(s)" in caption.inner_text()
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
        # Nothing of the scene lies under the caption (issue 58: it covered the key): with the
        # caption hidden, the band it stood in is empty background.
        box = caption.bounding_box()
        assert box is not None and box["height"] <= 0.33 * VIEWPORT["height"]
        caption.evaluate("element => { element.style.display = 'none'; }")
        page.wait_for_timeout(500)
        bare = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")).astype(int)
        band = bare[int(box["y"]) :]
        drawn = (band < 235).any(axis=2)
        assert drawn.mean() < 0.002, f"{drawn.mean():.4f} of the caption's band is drawn on"
        browser.close()
    assert outside == [], f"the page asked for {outside}"
    # The mode body is drawn (its clay colour, shaded, in the middle column above the floor:
    # the photo's wall is clay-like too) and the photo (many distinct colours).
    height, width = shot.shape[:2]
    middle = shot[int(0.25 * height) : int(0.6 * height), int(0.42 * width) : int(0.64 * width)]
    clay = np.abs(middle - np.array(MODE_COLOUR)).max(axis=2) < 40
    assert clay.mean() > 0.05, f"no mode body drawn ({clay.mean():.4f} of the middle column)"
    colours = len(np.unique(shot.reshape(-1, 3) // 8, axis=0))
    assert colours > 200, f"only {colours} colours: the scene was not drawn"

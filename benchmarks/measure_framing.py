"""How much of the explorer's window its views fill: a headless Chromium screenshot of the live
app at 1400 x 900, and the share of the canvas left of the control panel that is not
background, with the rows and columns the drawings span, and how tall the most likely body is
drawn (its vertices projected through the browser's camera: pixels, and share of the height).

Runs the app in-process on the demo photo with the test double of the predictor
(``tests/test_explorer_double.py``), or the shipped model with ``--real``. Needs playwright and
Debian's chromium (/usr/bin/chromium), as the browser tests do.

Usage: python benchmarks/measure_framing.py [--real] [--compare] [--out shot.png]
[--width 1400 --height 900] [--explorer-from OLD_TREE/explorer]
"""

from __future__ import annotations

import argparse
import io
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


PANEL_WIDTH_PX = 420
"""The floating control panel's width plus margin (as the app frames for)."""
BACKGROUND_TOLERANCE = 24
"""A pixel differs from the background when a channel differs by more than this (the floor
grid's faint lines stay background)."""


def filled_share(shot: np.ndarray, panel_px: int) -> dict[str, float]:
    """Share of the canvas left of the panel that is drawn on, and the share of its height and
    width the drawings span.

    Args:
        shot: ``(H, W, 3)`` uint8 screenshot of the page.
        panel_px: width of the floating panel on the right (excluded).
    """
    free = shot[:, : shot.shape[1] - panel_px].astype(np.int16)
    corners = np.stack([free[2, 2], free[2, -3], free[-3, 2], free[-3, -3]])
    background = np.median(corners, axis=0)
    drawn = np.abs(free - background).max(axis=2) > BACKGROUND_TOLERANCE
    rows, cols = np.flatnonzero(drawn.any(axis=1)), np.flatnonzero(drawn.any(axis=0))
    return {
        "pixels": float(drawn.mean()),
        "height": (rows[-1] - rows[0] + 1) / drawn.shape[0] if len(rows) else 0.0,
        "width": (cols[-1] - cols[0] + 1) / drawn.shape[1] if len(cols) else 0.0,
    }


def body_height_px(app, page) -> float:
    """Pixels between the most likely body's highest and lowest vertices on the canvas (the
    body's node stands at the world origin, turned a half turn about x)."""
    from test_explorer_e2e import world_to_canvas

    vertices = np.asarray(app.view.mode_vertices, dtype=np.float64)
    world = vertices * np.array([1.0, -1.0, -1.0])
    rows = world_to_canvas(app, world, page)[:, 1]
    return float(rows.max() - rows.min())


def screenshot(app, width: int, height: int) -> tuple[np.ndarray, float]:
    """The page at ``width`` x ``height`` once the first view is drawn and the camera rests,
    and the most likely body's drawn height in pixels."""
    import playwright.sync_api as playwright_api
    from test_explorer_e2e import CANVAS_SHOWN, camera_settled, launch_chromium

    with playwright_api.sync_playwright() as playwright:
        browser = launch_chromium(playwright)
        page = browser.new_page(viewport={"width": width, "height": height})
        page.goto(app.url)
        page.wait_for_function(CANVAS_SHOWN, timeout=60_000)
        deadline = time.monotonic() + 60
        while (app.view is None or not app.server.get_clients()) and time.monotonic() < deadline:
            time.sleep(0.1)
        app.wait_idle(60)
        camera_settled(app)
        # Notifications ("Software WebGL rendering detected") are not the framing's.
        page.add_style_tag(content=".mantine-Notifications-root { display: none !important; }")
        shot = stable_screenshot(page)
        body_px = body_height_px(app, page)
        browser.close()
    return shot, body_px


def stable_screenshot(page, timeout_s: float = 30.0) -> np.ndarray:
    """A screenshot once two taken a second apart agree (nodes fade in over a few seconds
    with software WebGL; labels appear late)."""
    last = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(1.0)
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
        if np.abs(shot.astype(np.int16) - last).mean() < 0.05:
            return shot
        last = shot
    return last


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", action="store_true", help="the shipped model on its photo")
    parser.add_argument("--width", type=int, default=1400)
    parser.add_argument("--height", type=int, default=900)
    parser.add_argument("--out", default=None, help="also save the screenshot here")
    parser.add_argument(
        "--compare", action="store_true", help="with B's columns (B: without the boxes)"
    )
    parser.add_argument(
        "--explorer-from", default=None, metavar="DIR",
        help="import hkpd.explorer from DIR (an older tree, e.g. from git archive) for a "
        "before/after comparison",
    )  # fmt: skip
    args = parser.parse_args()
    if args.explorer_from:
        import hkpd.explorer

        hkpd.explorer.__path__[:] = [str(Path(args.explorer_from).resolve())]
    from test_explorer_double import OcclusionAwareDouble

    from hkpd.explorer.app import ExplorerApp

    if args.real:
        from hkpd.explorer.demo_photo import shipped_photo
        from hkpd.explorer.provider import PredictorProvider
        from hkpd.prediction.image_input import load_image

        provider, image = PredictorProvider(device="cpu"), load_image(shipped_photo()).pixels
    else:
        provider = OcclusionAwareDouble()
        image = provider.scene.image
    app = ExplorerApp(provider, image, port=0, num_samples=100, num_displayed=10)
    try:
        if args.compare:
            app.wait_idle(300)
            app.panels.compare.menu.value = "B: without the boxes"  # what a click does
            app.wait_idle(300)
        shot, body_px = screenshot(app, args.width, args.height)
    finally:
        app.stop()
    if args.out:
        Image.fromarray(shot).save(args.out)
    share = filled_share(shot, PANEL_WIDTH_PX)
    load = os.getloadavg()[0]
    model = "shipped model" if args.real else "test double"
    model += " + compare" if args.compare else ""
    print(f"{platform.node()} · {os.cpu_count()} CPUs · load {load:.1f} · "
          f"{args.width} x {args.height} · {model}")  # fmt: skip
    print("| drawn pixels | height spanned | width spanned | body height px (share) |")
    print("|---:|---:|---:|---:|")
    print(f"| {share['pixels']:.1%} | {share['height']:.1%} | {share['width']:.1%} "
          f"| {body_px:.0f} ({body_px / args.height:.1%}) |")  # fmt: skip


if __name__ == "__main__":
    main()

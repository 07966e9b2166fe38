"""Render the three teaching lessons of docs/explorer.md with the shipped model on the shipped
CC0 photo, and print the numbers the lessons quote.

For each lesson it builds the explorer's scene as a page (``hkpd.explorer.show``, the same call
as docs/notebooks/lessons.ipynb), opens it from file:// in headless Chromium (network off) and
keeps a small PNG:

- ``docs/figures/lesson_hide_shin.png``: a box over the right shin;
- ``docs/figures/lesson_sharpen_elbow.png``: the left elbow's concentration times 10;
- ``docs/figures/lesson_network_only.png``: the network alone (no keypoint evidence);
- ``docs/figures/lesson_slide_forearm.png``: the slide example, a box over the right forearm
  (:data:`SLIDE_BOX`, chosen with ``measure_slide_boxes.py``: the box that changes the page
  most).

It also prints lesson 4's numbers (the person mask in the fit: the shape coefficients beta_0
and beta_2 with their std, and the mean vertex uncertainty, without and with the mask).

    python docs/figures/scripts/make_explorer_lessons.py [--pages OUT_FOLDER] [--numbers-only]
"""

from __future__ import annotations

import argparse
import io
import os
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from hkpd.explorer import show
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.explorer.posterior_view import part_uncertainty
from hkpd.prediction import BodyPosterior, Predictor, load_image

FIGURES = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--use-angle=gl-egl", "--ignore-gpu-blocklist"]
VIEWPORT = {"width": 1400, "height": 760}
WIDTH = 900
"""Width of the kept PNGs (pixels)."""
SLIDE_BOX = (377, 255, 473, 290)
"""docs/explorer.md's slide example: the right elbow and wrist of the shipped photo, padded."""


def shin_box(posterior: BodyPosterior) -> tuple[float, float, float, float]:
    """A box around the detected right knee and ankle (photo pixels), a quarter shin padded."""
    keypoints = posterior.keypoints.numpy()
    knee, ankle = keypoints[14], keypoints[16]
    pad = 0.25 * float(np.hypot(*(knee - ankle)))
    low, high = np.minimum(knee, ankle) - pad, np.maximum(knee, ankle) + pad
    return (*np.round(low).tolist(), *np.round(high).tolist())


def limbs_cm(posterior: BodyPosterior) -> dict[str, float]:
    """Mean vertex uncertainty (cm, 100 samples, seed 0) of the parts the lessons talk about."""
    parts = part_uncertainty(
        posterior.vertex_uncertainty(100, seed=0).numpy(), posterior.body.part_labels.numpy()
    )
    return {
        "right shin": 100 * parts["right_knee"],
        "left shin": 100 * parts["left_knee"],
        "left forearm": 100 * parts["left_elbow"],
        "right forearm": 100 * parts["right_elbow"],
        "right hand": 100 * parts["right_wrist"],
        "left hand": 100 * parts["left_wrist"],
    }


def mask_lesson(predictor: Predictor, photo: np.ndarray) -> None:
    """Print lesson 4's numbers: beta_0 and beta_2 (mean ± std), the whole body's mean vertex
    uncertainty (cm, 100 samples, seed 0) and the prediction's seconds, without and with the
    person mask in the fit."""
    import time

    for mask in (False, True):
        predictor.silhouette_evidence = mask
        started = time.perf_counter()
        posterior = predictor.predict(photo)
        seconds = time.perf_counter() - started
        mean, std = posterior.shape_mean.tolist(), posterior.shape_std.tolist()
        whole = 100 * float(posterior.vertex_uncertainty(100, seed=0).mean())
        print(f"person mask {'on ' if mask else 'off'}: beta_0 {mean[0]:.2f} ± {std[0]:.2f}, "
              f"beta_2 {mean[2]:.2f} ± {std[2]:.2f}, whole body {whole:.1f} cm, "
              f"sex {posterior.sex} {posterior.sex_probability:.2f}, {seconds:.2f} s")  # fmt: skip
    predictor.silhouette_evidence = False


def screenshot(page_html: str, target: Path) -> None:
    """Open the page from a file in Chromium (offline) and keep a ``WIDTH``-pixel PNG."""
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as folder, sync_playwright() as playwright:
        path = Path(folder) / "page.html"
        path.write_text(page_html, encoding="utf-8")
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM, args=CHROMIUM_ARGS,
            env={**os.environ, "EGL_PLATFORM": "surfaceless"},
        )  # fmt: skip
        context = browser.new_context(viewport=VIEWPORT)
        context.set_offline(True)
        page = context.new_page()
        page.goto(path.as_uri())
        page.wait_for_function("() => [...document.querySelectorAll('canvas')].length > 0")
        page.wait_for_timeout(6000)
        # viser warns about software WebGL (headless Chromium has no GPU): close the notice.
        for button in page.locator(".mantine-Notification-closeButton").all():
            button.click()
        page.wait_for_timeout(500)
        shot = Image.open(io.BytesIO(page.screenshot())).convert("RGB")
        browser.close()
    height = round(shot.height * WIDTH / shot.width)
    small = shot.resize((WIDTH, height), Image.LANCZOS).quantize(colors=128)
    small.save(target, optimize=True)
    print(f"wrote {target} ({target.stat().st_size / 1e3:.0f} kB)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pages", type=Path, default=None, help="also keep the HTML pages here")
    parser.add_argument("--numbers-only", action="store_true", help="print, take no screenshot")
    args = parser.parse_args()
    predictor = Predictor.from_pretrained(device="cpu")
    photo = load_image(shipped_photo()).pixels
    mask_lesson(predictor, photo)
    plain = predictor.predict(photo)
    box = shin_box(plain)
    lessons = {
        "lesson_hide_shin": predictor.predict(photo, occluders=[box]),
        "lesson_sharpen_elbow": plain.with_concentration("left_elbow", 10.0),
        "lesson_network_only": predictor.predict(photo, evidence=False),
        "lesson_slide_forearm": predictor.predict(photo, occluders=[SLIDE_BOX]),
    }
    print(f"shin box {box}")
    print(f"as predicted ({plain.evidence_fit.evidence_count} keypoints as evidence):",
          {k: round(v, 2) for k, v in limbs_cm(plain).items()})  # fmt: skip
    for name, posterior in lessons.items():
        fit = posterior.evidence_fit
        counted = fit.evidence_count if posterior.conditioned and fit is not None else 0
        print(f"{name} ({counted} keypoints as evidence):",
              {k: round(v, 2) for k, v in limbs_cm(posterior).items()})  # fmt: skip
        if args.numbers_only:
            continue
        page = show(posterior, photo_name="warrior_lunge.jpg", model_name="the shipped model")
        if args.pages is not None:
            page.save(args.pages / f"{name}.html", force=True)
        screenshot(page.html, FIGURES / f"{name}.png")


if __name__ == "__main__":
    main()

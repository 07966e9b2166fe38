"""Render ``docs/figures/upright_reading.png``: the network alone on a lying person, reading
the crop as it is against reading an upright copy.

The shipped CC0 photo turned by 90° (the person then lies across the picture); two panels of
the network's own posterior (``evidence=False``): ``upright=False`` and the default
``upright=True``, each with the detected keypoints, the reprojected mode and 10 samples, and
the mode's mean 2D distance from the detected keypoints.

    python docs/figures/scripts/make_upright_reading_figure.py
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.prediction import Predictor
from hkpd.prediction.exports.overview import BACKGROUND, TEXT, _font, draw_skeletons

FIGURE = Path(__file__).resolve().parents[1] / "upright_reading.png"
SIZE = 360


def _panel(predictor: Predictor, photo: np.ndarray, upright: bool) -> tuple[np.ndarray, str]:
    posterior = predictor.predict(photo, evidence=False, upright=upright)
    mode = posterior.mode().keypoints2d[0].numpy()
    samples = posterior.sample(10, seed=0).keypoints2d.numpy()
    detected = posterior.keypoints.numpy()
    kept = posterior.confidences.numpy() >= 0.6
    error = float(np.linalg.norm(mode[kept] - detected[kept], axis=1).mean())
    skeleton = draw_skeletons(
        posterior.network_input.image, posterior.crop, detected,
        posterior.confidences.numpy(), mode, samples, SIZE,
    )  # fmt: skip
    turned = posterior.upright_tilt_degrees
    label = "read as it is" if turned is None else f"read turned upright ({turned:+.0f}°)"
    return skeleton, f"{label}: mode {error:.0f} px from the keypoints"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args()
    photo = np.asarray(Image.open(shipped_photo()).convert("RGB").rotate(90, expand=True))
    predictor = Predictor.from_pretrained(device="cpu")
    panels = [_panel(predictor, photo, upright) for upright in (False, True)]
    gap, title = 12, 30
    canvas = Image.new("RGB", (2 * SIZE + 3 * gap, SIZE + title + gap), BACKGROUND)
    draw = ImageDraw.Draw(canvas)
    font = _font(14)
    for index, (skeleton, label) in enumerate(panels):
        x = gap + index * (SIZE + gap)
        canvas.paste(Image.fromarray(skeleton), (x, title))
        draw.text((x, title - 8), label, fill=TEXT, font=font, anchor="ls")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out)
    predictor.close()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

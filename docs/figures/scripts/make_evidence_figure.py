"""Render ``docs/figures/evidence_posterior.png``: the network's posterior against the evidence one.

On a CC0 photo (``yogait_war0.jpg`` from ``../shared/data/demo_photos``, IBM CODAIT team), two
rows (network only; conditioned on the 2D keypoints) and four panels each: the photo with the
detected keypoints, the reprojected mode and 10 samples; the mode coloured by per-vertex
uncertainty; the same two with a box over the right shin (its keypoints are then not evidence).

    python docs/figures/scripts/make_evidence_figure.py ../shared/data/demo_photos/yogait_war0.jpg \
        --box 640 470 760 640
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from hkpd.prediction import Predictor
from hkpd.prediction.exports.overview import (
    BACKGROUND,
    TEXT,
    _font,
    draw_colour_bar,
    draw_skeletons,
    render_uncertainty_views,
)
from hkpd.prediction.exports.uncertainty_colours import UncertaintyColourScale

FIGURE = Path(__file__).resolve().parents[1] / "evidence_posterior.png"
HEIGHT = 300


def _panels(predictor: Predictor, photo: Path, occluders, evidence: bool, scale):
    posterior = predictor.predict(photo, occluders=occluders, evidence=evidence)
    prepared = posterior.network_input
    mode = posterior.mode()
    samples = posterior.sample(10, seed=0)
    uncertainty = posterior.vertex_uncertainty(100).numpy()
    skeleton = draw_skeletons(
        prepared.image, posterior.crop, posterior.keypoints.numpy(),
        posterior.confidences.numpy(), mode.keypoints2d[0].numpy(),
        samples.keypoints2d.numpy(), HEIGHT,
    )  # fmt: skip
    if occluders:
        image = Image.fromarray(skeleton)
        draw = ImageDraw.Draw(image)
        for x0, y0, x1, y1 in occluders:
            corners = posterior.crop.image_to_crop(np.array([[x0, y0], [x1, y1]], float))
            corners = corners * HEIGHT / posterior.crop.size
            draw.rectangle(tuple(corners.flatten()), outline=(230, 40, 40), width=3)
        skeleton = np.asarray(image)
    front, _, masks = render_uncertainty_views(
        mode.vertices[0], posterior.body.faces, uncertainty, scale, HEIGHT
    )
    columns = masks[0].any(0).nonzero()[0]
    front = front[:, max(0, columns.min() - 10) : columns.max() + 10]
    return skeleton, front, 100 * float(uncertainty.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("photo", type=Path)
    parser.add_argument("--box", type=float, nargs=4, required=True, metavar="X")
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args()
    predictor = Predictor.from_pretrained(device="cpu")
    scale = UncertaintyColourScale()
    rows = []
    for evidence in (False, True):
        clean = _panels(predictor, args.photo, None, evidence, scale)
        covered = _panels(predictor, args.photo, [tuple(args.box)], evidence, scale)
        rows.append((evidence, clean, covered))
    gap, title = 10, 34
    bar = draw_colour_bar(scale, HEIGHT)
    body_width = max(panels[1].shape[1] for _, *both in rows for panels in both)
    width = 2 * (HEIGHT + body_width) + bar.shape[1] + 6 * gap
    canvas = Image.new("RGB", (width, 2 * (HEIGHT + title) + gap), BACKGROUND)
    draw = ImageDraw.Draw(canvas)
    font = _font(15)
    for index, (evidence, clean, covered) in enumerate(rows):
        top = index * (HEIGHT + title + gap) + title
        label = "with 2D evidence" if evidence else "network only"
        x = gap
        for name, (skeleton, front, mean_cm) in (("photo", clean), ("shin covered", covered)):
            canvas.paste(Image.fromarray(skeleton), (x, top))
            draw.text((x, top - 8), f"{label}: {name}", fill=TEXT, font=font, anchor="ls")
            x += skeleton.shape[1] + gap
            canvas.paste(Image.fromarray(front), (x, top))
            draw.text((x, top - 8), f"mean {mean_cm:.1f} cm", fill=TEXT, font=font, anchor="ls")
            x += body_width + gap
        canvas.paste(Image.fromarray(bar), (x, top))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

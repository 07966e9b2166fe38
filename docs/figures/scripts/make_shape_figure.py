"""Render ``docs/figures/shape_silhouette.png``: the evidence posterior's mode silhouette with
the keypoints only and with BlazePose's person mask as evidence too.

One row per photo: the shipped CC0 photo (:func:`hkpd.explorer.demo_photo.shipped_photo`)
first, then the photos given on the command line (for the committed figure only CC0 ones: the
``yogait_*`` photos of ``../shared/data/demo_photos``, IBM CODAIT team). Two panels per row,
both the photo cut to the network's crop box with BlazePose's person mask outlined (blue,
probability 0.5), the detected keypoints (white dots) and the mode's skeleton and silhouette
outline (red): left, the evidence posterior fitted to the keypoints only
(``Predictor(silhouette_evidence=False)``, the default); right, to the keypoints and the mask
(``Predictor(silhouette_evidence=True)``). Each panel's title gives the IoU of the mode's
silhouette with the mask in the crop.

    python docs/figures/scripts/make_shape_figure.py \
        ../shared/data/demo_photos/yogait_t5.jpg ../shared/data/demo_photos/yogait_test_y.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw

from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.prediction import Predictor
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.person_mask import MASK_THRESHOLD
from hkpd.prediction.exports.overview import (
    BACKGROUND,
    MASK_COLOUR,
    MODE_COLOUR,
    TEXT,
    Outlines,
    _font,
    draw_skeletons,
    mesh_silhouette,
)
from hkpd.prediction.posterior import BodyPosterior

FIGURE = Path(__file__).resolve().parents[1] / "shape_silhouette.png"
SIZE = 360
"""Side of each panel, pixels."""
IOU_CROP = 256
"""Crop side, pixels, at which the mode's silhouette is compared with the mask."""


def _mode_outlines(posterior: BodyPosterior) -> tuple[Outlines, np.ndarray]:
    """The mask and mode-silhouette outlines of ``posterior`` and its ``(17, 2)`` mode
    keypoints, original-photo pixels (as ``hkpd-predict``'s overview draws them)."""
    mode = posterior.mode()
    ndc = weak_perspective_project(mode.vertices, posterior.camera.expand(1, 3))
    vertices2d = posterior.crop.crop_to_image(ndc_to_pixels(ndc, posterior.crop.size))
    outlines = Outlines(
        person_mask=posterior.network_input.detection.person_mask,
        mode_vertices2d=torch.as_tensor(vertices2d)[0].detach().cpu().double().numpy(),
        faces=torch.as_tensor(posterior.body.faces).cpu().numpy(),
    )
    return outlines, mode.keypoints2d[0].cpu().numpy()


def _mask_iou(posterior: BodyPosterior, outlines: Outlines) -> float:
    """IoU of the mode's silhouette with the person mask (> 0.5) in the crop at
    :data:`IOU_CROP` pixels (NaN without a mask)."""
    if outlines.person_mask is None or outlines.mode_vertices2d is None:
        return float("nan")
    view = CropTransform(posterior.crop.centre, posterior.crop.side, IOU_CROP)
    mask = outlines.person_mask.in_frame(view.affine_matrix(), (IOU_CROP, IOU_CROP))
    mask = mask > MASK_THRESHOLD
    points = view.image_to_crop(outlines.mode_vertices2d)
    body = mesh_silhouette(points, outlines.faces, (IOU_CROP, IOU_CROP))
    return float((mask & body).sum() / max(1, (mask | body).sum()))


def _panel(predictor: Predictor, photo: Path) -> tuple[np.ndarray, float]:
    """The photo panel of the evidence posterior of ``predictor`` and its mode's mask IoU."""
    posterior = predictor.predict(photo, evidence=True)
    outlines, mode_keypoints = _mode_outlines(posterior)
    detection = posterior.network_input.detection
    picture = draw_skeletons(
        posterior.network_input.image, posterior.crop, detection.keypoints,
        detection.confidences, mode_keypoints, None, SIZE, outlines,
    )  # fmt: skip
    return picture, _mask_iou(posterior, outlines)


def _legend(draw: ImageDraw.ImageDraw, x: int, y: int) -> None:
    font = _font(14)
    for colour, label in ((MASK_COLOUR, "BlazePose person mask"), (MODE_COLOUR, "mode")):
        draw.line((x, y, x + 22, y), fill=colour, width=4)
        draw.text((x + 27, y), label, fill=TEXT, font=font, anchor="lm")
        x += 27 + int(draw.textlength(label, font=font)) + 18


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("photos", type=Path, nargs="*", help="photos after the shipped one")
    parser.add_argument("--model", default=None, help="checkpoint (default: the shipped model)")
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args()
    predictors = [
        Predictor.from_pretrained(args.model, device="cpu", silhouette_evidence=silhouette)
        for silhouette in (False, True)
    ]
    labels = ("keypoints only", "keypoints + mask")
    photos = [shipped_photo(), *args.photos]
    gap, title, legend = 10, 26, 30
    canvas = Image.new(
        "RGB", (2 * SIZE + 3 * gap, len(photos) * (SIZE + title) + legend + gap), BACKGROUND
    )
    draw = ImageDraw.Draw(canvas)
    font = _font(15)
    for row, photo in enumerate(photos):
        top = row * (SIZE + title) + title
        for column, (predictor, label) in enumerate(zip(predictors, labels, strict=True)):
            picture, iou = _panel(predictor, photo)
            x = gap + column * (SIZE + gap)
            canvas.paste(Image.fromarray(picture), (x, top))
            text = f"{photo.name}, {label}" if column == 0 else label
            text += f": IoU with mask {iou:.2f}"
            draw.text((x, top - 7), text, fill=TEXT, font=font, anchor="ls")
            print(f"{photo.name}\t{label}\tmode silhouette IoU with the mask {iou:.3f}")
    _legend(draw, gap, len(photos) * (SIZE + title) + legend // 2 + 4)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""The figure of docs/shape.md "Sex and measurements": one photo, its body as each sex.

For one photo (default: the shipped CC0 photo) the shipped predictor's posterior is read four
times: the sex left to the photo, stated female, stated male, and stated male with a height
and a mass. Each most likely shape is drawn standing (rest pose, front and side, the clay
colour of the explorer) under its sex with probability and its measurements with ±.

    python docs/experiments/sex_figure.py [PHOTO] --height 1.85 --mass 95 \
        --out docs/figures/shape_sex_and_measurements.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import torch
from PIL import Image, ImageDraw, ImageFont

from hkpd.assets import shipped_file
from hkpd.prediction import Predictor
from hkpd.prediction.posterior import BodyPosterior
from hkpd.rendering.lighting import Lighting
from hkpd.rendering.mesh_renderer import MeshRenderer

CLAY = (0.78, 0.76, 0.72)
PANEL = 300
VIEW_DISTANCE_M = 6.0


def render_standing(posterior: BodyPosterior, size: int = PANEL) -> np.ndarray:
    """``(size, 2 size, 3)`` uint8: the most likely shape at rest, front and side, camera
    looking at the body's front (OpenCV axes: y down)."""
    body = posterior.body
    vertices = body.tpose(posterior.shape_mean[None].float())[0].cpu()
    # Arms down a little would be kinder; the rest pose shows the shape without the pose.
    points = vertices * torch.tensor([1.0, -1.0, -1.0])  # SMPL (y up, +z front) -> camera
    points = points - (points.amax(0) + points.amin(0)) / 2
    side = points @ torch.tensor([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]).T
    views = torch.stack([points, side])
    views[..., 2] += VIEW_DISTANCE_M
    height_px = 2 * size
    focal = 0.92 * height_px * VIEW_DISTANCE_M / 2.0  # 2 m fill 92 % of the image height
    renderer = MeshRenderer(body.faces.cpu(), image_size=height_px)
    light = Lighting(
        ambient=torch.full((2,), 0.5), diffuse=torch.full((2,), 0.6),
        specular=torch.full((2,), 0.08),
        direction=torch.tensor([[-0.35, -0.5, -0.79]]).expand(2, 3),
        colour=torch.ones(2, 3), shininess=torch.full((2,), 20.0),
    )  # fmt: skip
    albedo = torch.tensor(CLAY).expand(2, body.faces.shape[0], 3)
    output = renderer.render(views, torch.full((2,), focal), albedo, light)
    panels = []
    for rgb, mask in zip(output.rgb, output.mask, strict=True):
        image = np.where(mask[..., None].numpy(), rgb.permute(1, 2, 0).numpy(), 1.0)
        image = cv2.resize(image, (size, size), interpolation=cv2.INTER_AREA)
        panels.append((image.clip(0, 1) * 255).astype(np.uint8))
    return np.concatenate(panels, axis=1)


def caption(title: str, posterior: BodyPosterior) -> list[str]:
    """The panel's lines: what was stated, the sex with its probability, measurements ± std."""
    measured = posterior.measurements()
    sex = f"{posterior.sex} {100 * posterior.sex_probability:.0f} %"
    lines = [title, sex + (" (stated)" if posterior.sexes.stated else "")]
    for name, label, unit, scale in (
        ("height_m", "height", "cm", 100), ("mass_kg", "mass", "kg", 1),
        ("chest_m", "chest", "cm", 100), ("waist_m", "waist", "cm", 100),
        ("hip_m", "hip", "cm", 100), ("shoulder_width_m", "shoulders", "cm", 100),
    ):  # fmt: skip
        mean, std = measured[name]
        lines.append(f"{label} {scale * mean:.0f} ± {scale * std:.0f} {unit}")
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photo", nargs="?", type=Path)
    parser.add_argument("--height", type=float, default=1.85)
    parser.add_argument("--mass", type=float, default=95.0)
    parser.add_argument("--out", type=Path, default=Path("shape_sex_and_measurements.png"))
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    photo = args.photo or shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")
    predictor = Predictor.from_pretrained(device="cpu")
    stated = f"male, {args.height:g} m, {args.mass:g} kg"
    readings = [
        ("sex from the photo", predictor.predict(photo)),
        ("stated: female", predictor.predict(photo, sex="female")),
        ("stated: male", predictor.predict(photo, sex="male")),
        (f"stated: {stated}", predictor.predict(
            photo, sex="male", measurements={"height_m": args.height, "mass_kg": args.mass}
        )),
    ]  # fmt: skip
    text_height, width = 190, PANEL
    photo_panel = Image.open(photo).convert("RGB")
    photo_panel.thumbnail((PANEL, 2 * PANEL + text_height))
    sheet = Image.new("RGB", (photo_panel.width + width * 4, PANEL * 2 + text_height), "white")
    sheet.paste(photo_panel, (0, 0))
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default(size=16)
    for index, (title, posterior) in enumerate(readings):
        x = photo_panel.width + index * width
        standing = render_standing(posterior)  # front and side, side by side
        front, side = standing[:, :PANEL], standing[:, PANEL:]
        sheet.paste(Image.fromarray(np.concatenate([front, side], axis=0)), (x, 0))
        for row, line in enumerate(caption(title, posterior)):
            draw.text((x + 12, 2 * PANEL + 6 + row * 21), line, fill="black", font=font)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out)
    print(f"wrote {args.out}")
    predictor.close()


if __name__ == "__main__":
    main()

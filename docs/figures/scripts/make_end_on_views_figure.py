"""Render ``docs/figures/end_on_views.png``: why nearly end-on views stay hard.

Four views of the fixed any-orientation synthetic test split whose true torso points more than
60° out of the picture (seen from high above or below). Each panel shows the edge image the
network reads, the true keypoints (white), the network's most likely body as the predictor reads
it (red; upright copy, mirror reading) and the *true* body through its best weak-perspective
camera (blue): even that misses, since a weak-perspective camera draws near and far parts of the
body at one scale. docs/model_history.md, section 5 ("Where the any-orientation error is").

    python docs/figures/scripts/make_end_on_views_figure.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))
from experiment_arguments import parse_experiment_arguments
from mirror_and_perspective_readings import best_camera

from hkpd.body.root_relative import pelvis_relative_body
from hkpd.camera_conventions import ndc_to_pixels, weak_perspective_project
from hkpd.coco_keypoints import COCO17_LIMBS
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.exports.overview import BACKGROUND, TEXT, _font
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.synthesis.orientation import ANY_ORIENTATION

FIGURE = Path(__file__).resolve().parents[1] / "end_on_views.png"
PANEL = 300
PANELS = 4
END_ON_DEGREES = 60.0
NETWORK, FLOOR, TRUTH = (220, 50, 32), (40, 90, 220), (255, 255, 255)


def _skeleton(draw: ImageDraw.ImageDraw, points: np.ndarray, colour, width: int) -> None:
    for a, b in COCO17_LIMBS:
        draw.line([tuple(points[a]), tuple(points[b])], fill=colour, width=width)


def _panel(edges: np.ndarray, truth: np.ndarray, network: np.ndarray, floor: np.ndarray,
           visible: np.ndarray) -> Image.Image:  # fmt: skip
    """One ``PANEL``-pixel panel; points in the edge image's pixels."""
    scale = PANEL / edges.shape[0]
    strength = edges.astype(np.float32) / max(float(edges.max()), 1e-6)
    faded = (255 - strength * 110).astype(np.uint8)
    image = Image.fromarray(faded).resize((PANEL, PANEL), Image.NEAREST).convert("RGB")
    draw = ImageDraw.Draw(image)
    for points, colour in ((floor, FLOOR), (network, NETWORK)):
        _skeleton(draw, (points + 0.5) * scale, colour, 3)
    for u, v in (truth[visible] + 0.5) * scale:
        draw.ellipse([u - 4, v - 4, u + 4, v + 4], fill=TRUTH, outline=(0, 0, 0))
    return image


def _visible_error(points: np.ndarray, truth: np.ndarray, visible: np.ndarray, size: int) -> float:
    """Mean distance over the visible keypoints, px at 256."""
    return float(np.linalg.norm(points - truth, axis=-1)[visible].mean() * 256.0 / size)


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    torch.set_num_threads(1)
    network, generator = network_and_generator(
        arguments.checkpoint, arguments.poses, "cpu", orientation=ANY_ORIENTATION
    )
    network.eval()
    body = generator.body
    reader = ProxyReader(network, ReadingConfig(), body=body)
    panels: list[tuple[Image.Image, str]] = []
    with torch.no_grad():
        for batch in fixed_batches(generator, arguments.count):
            truth_body, _ = pelvis_relative_body(
                body, batch.betas, batch.body_pose, batch.global_orient
            )
            torso = truth_body[:, [5, 6]].mean(1) - truth_body[:, [11, 12]].mean(1)
            out = torch.rad2deg(torch.asin(torso[:, 2].abs() / torso.norm(dim=-1)))
            chosen = ((out > END_ON_DEGREES) & (batch.visible.sum(1) >= 12)).nonzero().flatten()
            if len(chosen) == 0:
                continue
            size = int(batch.proxy.shape[-1])
            output = reader(batch.proxy, batch.keypoints2d)
            mode, _ = pelvis_relative_body(
                body, output.shape_mean, output.pose_distribution().mode, output.global_orient
            )
            network_points = ndc_to_pixels(weak_perspective_project(mode, output.camera), size)
            camera = best_camera(truth_body, batch, weak_perspective_project, output.camera, size)
            floor_points = ndc_to_pixels(weak_perspective_project(truth_body, camera), size)
            for index in chosen.tolist():
                truth = batch.keypoints2d[index].numpy()
                visible = batch.visible[index].numpy()
                points = network_points[index].numpy(), floor_points[index].numpy()
                edges = batch.proxy[index, 0].numpy()
                label = (f"torso {out[index]:.0f}° out of the picture: network "
                         f"{_visible_error(points[0], truth, visible, size):.0f} px, true body "
                         f"{_visible_error(points[1], truth, visible, size):.0f} px")  # fmt: skip
                panels.append((_panel(edges, truth, *points, visible), label))
                if len(panels) == PANELS:
                    break
            if len(panels) == PANELS:
                break
    gap, title, legend = 12, 44, 30
    canvas = Image.new(
        "RGB", (PANELS * PANEL + (PANELS + 1) * gap, PANEL + title + legend + gap), BACKGROUND
    )
    draw = ImageDraw.Draw(canvas)
    font = _font(12)
    for index, (panel, label) in enumerate(panels):
        x = gap + index * (PANEL + gap)
        canvas.paste(panel, (x, title))
        words = label.split(": ")
        draw.text((x, 6), words[0] + ":", fill=TEXT, font=font, anchor="la")
        draw.text((x, 22), words[1], fill=TEXT, font=font, anchor="la")
    y = title + PANEL + 18
    entries = ((TRUTH, "true keypoints"), (NETWORK, "network, most likely body"),
               (FLOOR, "true body, best weak-perspective camera"))  # fmt: skip
    x = gap
    for colour, text in entries:
        draw.rectangle([x, y - 6, x + 18, y + 2], fill=colour, outline=(0, 0, 0))
        draw.text((x + 24, y + 2), text, fill=TEXT, font=_font(13), anchor="ls")
        x += 40 + int(draw.textlength(text, font=_font(13)))
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(FIGURE)
    print(f"wrote {FIGURE}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

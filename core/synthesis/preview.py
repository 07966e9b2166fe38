"""``hkpd-synth-preview``: a picture of what the network is trained on.

For each sample it shows four panels: the synthetic RGB crop, its Canny edges, the joint
heatmaps (coloured per joint) and the ground-truth skeleton over the RGB crop (green joints are
visible, red ones hidden or out of frame; grey lines are the input keypoints after noise).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
import torch

from hkpd.coco_keypoints import COCO17_LIMBS
from hkpd.poses import pose_source
from hkpd.synthesis.generator import (
    RenderedBatch,
    SyntheticDataConfig,
    SyntheticDataGenerator,
    batch_seed,
)

_JOINT_COLOURS = (
    np.array(
        [cv2.cvtColor(np.uint8([[[int(h), 220, 255]]]), cv2.COLOR_HSV2RGB)[0, 0]
         for h in np.linspace(0, 170, 17)]
    ).astype(np.float32) / 255.0
)  # fmt: skip


def heatmap_picture(proxy: torch.Tensor) -> np.ndarray:
    """``(18, S, S)`` proxy -> ``(S, S, 3)`` uint8: each joint's heatmap in its own colour."""
    maps = proxy[1:].cpu().numpy()  # (17, S, S)
    picture = np.einsum("jhw,jc->hwc", maps, _JOINT_COLOURS)
    return (np.clip(picture, 0, 1) * 255).astype(np.uint8)


def skeleton_picture(
    image: np.ndarray, keypoints: np.ndarray, visible: np.ndarray, inputs: np.ndarray
) -> np.ndarray:
    """Draw the ground-truth skeleton (and the noisy input keypoints) over an RGB crop."""
    canvas = (image.astype(np.float32) * 0.6).astype(np.uint8).copy()
    scale = max(1, image.shape[0] // 128)
    for a, b in COCO17_LIMBS:
        pa, pb = (
            tuple(np.round(keypoints[a]).astype(int)),
            tuple(np.round(keypoints[b]).astype(int)),
        )
        cv2.line(canvas, pa, pb, (255, 255, 255), scale, cv2.LINE_AA)
    for point in inputs:
        cv2.drawMarker(canvas, tuple(np.round(point).astype(int)), (160, 160, 160),
                       cv2.MARKER_CROSS, 4 * scale, 1)  # fmt: skip
    for point, seen in zip(keypoints, visible, strict=True):
        colour = (40, 230, 40) if seen else (240, 40, 40)
        cv2.circle(canvas, tuple(np.round(point).astype(int)), 2 * scale, colour, -1, cv2.LINE_AA)
    return canvas


def preview_grid(rendered: RenderedBatch, columns: int = 2) -> np.ndarray:
    """All samples of a rendered batch as one ``uint8`` RGB picture, four panels per sample."""
    tiles = []
    batch = rendered.batch
    for index in range(batch.batch_size):
        image = rendered.images[index]
        edges = (batch.proxy[index, 0].cpu().numpy() * 255).astype(np.uint8)
        tile = np.concatenate(
            [
                image,
                np.repeat(edges[..., None], 3, -1),
                heatmap_picture(batch.proxy[index]),
                skeleton_picture(
                    image,
                    batch.keypoints2d[index].cpu().numpy(),
                    batch.visible[index].cpu().numpy(),
                    rendered.input_keypoints[index][rendered.input_present[index]].cpu().numpy(),
                ),
            ],
            axis=1,
        )
        tiles.append(np.pad(tile, ((2, 2), (2, 2), (0, 0)), constant_values=255))
    while len(tiles) % columns:
        tiles.append(np.full_like(tiles[0], 255))
    rows = [np.concatenate(tiles[i : i + columns], axis=1) for i in range(0, len(tiles), columns)]
    return np.concatenate(rows, axis=0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="hkpd-synth-preview",
        description="Write a grid of synthetic training samples: RGB, edges, heatmaps, skeleton.",
    )
    parser.add_argument("--out", type=Path, default=Path("synthetic_preview.png"))
    parser.add_argument("--poses", type=Path, help="pose bank .npz (default: procedural prior)")
    parser.add_argument("--split", default="train", help="pose bank split (train/val/test)")
    parser.add_argument("--backgrounds", type=Path, help="folder of background images")
    parser.add_argument("--count", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--image-size", type=int, default=256)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)

    try:
        poses = pose_source(args.poses, args.split)
        generator = SyntheticDataGenerator(
            poses,
            SyntheticDataConfig(image_size=args.image_size),
            device=args.device,
            background_dir=args.backgrounds,
        )
    except (FileNotFoundError, ValueError) as error:
        print(f"hkpd-synth-preview: {error}", file=sys.stderr)
        return 2
    rendered = generator.generate(args.count, batch_seed(args.seed, 0))
    picture = preview_grid(rendered)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))
    print(f"wrote {args.out} ({picture.shape[1]}x{picture.shape[0]} px, {args.count} samples)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The edges+mask network's mask plane, in training and on photos (docs/shape.md, section 4).

Top row: the person-probability plane of eight synthetic training examples (the test split's
poses, ``SyntheticDataConfig(image_proxy="edges+mask")``: the rendered silhouette degraded by
:class:`hkpd.synthesis.mask_noise.MaskNoise`, unknown where the occlusion augmentations hid the
body, blank in 10 % of the examples). Bottom row: BlazePose's person mask in the network's crop
for the shipped CC0 photo and the demo photos (``prepare_network_input(...,
image_proxy="edges+mask")``), what the network reads on a photo. White is 1, black 0; the edges
are drawn faintly in blue beneath.

    python docs/figures/scripts/make_mask_input_figure.py --poses poses.npz \\
        --photos ../shared/data/demo_photos
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.poses import pose_source
from hkpd.prediction.detection.keypoint_detector import KeypointDetector, NoPersonFoundError
from hkpd.prediction.network_input import prepare_network_input
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

OUT = Path(__file__).resolve().parents[1] / "mask_input.png"
SIZE = 128
COLUMNS = 8


def tile(edges: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``(S, S, 3)`` uint8: the mask in grey over faint blue edges."""
    grey = np.clip(mask, 0, 1)[..., None] * 255.0
    blue = np.clip(edges, 0, 1)[..., None] * np.array([40.0, 80.0, 160.0])
    return np.clip(np.maximum(grey, blue), 0, 255).astype(np.uint8)


def synthetic_tiles(poses: Path) -> list[np.ndarray]:
    config = SyntheticDataConfig(image_size=SIZE, image_proxy="edges+mask")
    generator = SyntheticDataGenerator(pose_source(poses, "test"), config, "cpu")
    proxy = generator.generate(COLUMNS, 5).batch.proxy
    return [tile(p[0].numpy(), p[1].numpy()) for p in proxy]


def photo_tiles(photos: Path) -> list[np.ndarray]:
    detector = KeypointDetector()
    paths = [shipped_photo(), *sorted(photos.glob("*.jpg"))]
    tiles = []
    for path in paths:
        try:
            prepared = prepare_network_input(
                str(path), detector, crop_size=SIZE, image_proxy="edges+mask"
            )
        except NoPersonFoundError:
            continue
        proxy = prepared.proxy.numpy()
        tiles.append(tile(proxy[0], proxy[1]))
        if len(tiles) == COLUMNS:
            break
    return tiles


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=Path, required=True)
    parser.add_argument("--photos", type=Path, required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)
    rows = [synthetic_tiles(args.poses), photo_tiles(args.photos)]
    blank = np.zeros((SIZE, SIZE, 3), np.uint8)
    grid = np.concatenate(
        [np.concatenate((row + [blank] * COLUMNS)[:COLUMNS], axis=1) for row in rows], axis=0
    )
    Image.fromarray(grid).resize((grid.shape[1] * 2, grid.shape[0] * 2), Image.NEAREST).save(OUT)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()

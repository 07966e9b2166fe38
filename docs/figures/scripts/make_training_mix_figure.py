"""Render ``docs/figures/training_mix.png``: a grid of synthetic training crops with the new
data mix (pose families, limb mixes, rolled and steep views, detector-like keypoint noise).

    python docs/figures/scripts/make_training_mix_figure.py --poses poses.npz
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

from hkpd.poses import pose_source
from hkpd.synthesis.generator import SyntheticDataGenerator
from hkpd.training.config import TrainConfig

FIGURE = Path(__file__).resolve().parents[1] / "training_mix.png"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", type=Path, help="pose bank (default: procedural prior)")
    parser.add_argument("--out", type=Path, default=FIGURE)
    parser.add_argument("--seed", type=int, default=4)
    args = parser.parse_args()
    config = TrainConfig(
        image_size=128, roll_probability=0.4, steep_view_probability=0.15,
        archetype_share=0.3, limb_mix_share=0.1, keypoint_noise_sigma=0.0175,
        keypoint_outlier_probability=0.06,
    )  # fmt: skip
    source = pose_source(args.poses, "train", config.pose_mix())
    generator = SyntheticDataGenerator(source, config.data_config())
    images = generator.generate(40, args.seed).images
    rows = [np.concatenate(list(images[i * 10 : (i + 1) * 10]), axis=1) for i in range(4)]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate(rows, axis=0)).save(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

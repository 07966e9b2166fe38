"""Which mask-noise settings make synthetic masks err as BlazePose's do? (docs/shape.md §1, §3)

BlazePose's person mask was measured against coco_mini's COCO masks (`hkpd-eval --coco
coco_mini --no-synthetic --mask-errors`, docs/shape.md section 1; train2017 is the split for
choosing anything). This script measures synthetic detector-like masks the same way: the
exact rendered silhouette plays the COCO mask, :func:`hkpd.synthesis.mask_noise.
detector_like_masks` the detector, both at a 256-pixel crop, with the same error breakdown
(:func:`hkpd.evaluation.mask_errors.compare_masks`: IoU, boundary and far false positives,
missed parts, signed edge offsets, blobs). Examples: the pose bank's ``val`` subjects (not the
test set), framed as in training, the whole silhouette known (the occlusion augmentations are
left out: a person in full view).

It prints one row per candidate setting beside BlazePose's train2017 rows, so that a setting can
be chosen whose errors match a person alone in the photo (the case the silhouette term assumes);
the last candidate is today's :class:`MaskNoise` defaults, chosen this way on 2026-12-05.

    python docs/experiments/mask_noise_calibration.py --poses poses.npz --count 200
"""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.mask_errors import compare_masks, summarise
from hkpd.poses import pose_source
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator, batch_seed
from hkpd.synthesis.mask_noise import MaskNoise, detector_like_masks

BLAZEPOSE_TRAIN2017 = {
    "BlazePose, train2017, alone (7)": {
        "mean_iou": 0.841, "missed_parts": 0.024, "background": 0.013,
        "offset_mean_px": -1.35, "offset_std_px": 3.05, "blobs_per_person": 0.57,
    },
    "BlazePose, train2017, all (43)": {
        "mean_iou": 0.686, "missed_parts": 0.104, "background": 0.130,
        "offset_mean_px": -1.18, "offset_std_px": 3.27, "blobs_per_person": 1.19,
    },
}  # fmt: skip
"""docs/shape.md section 1 (the COCO mask's coarse polygons are part of these errors)."""

COLUMNS = (
    "mean_iou", "boundary_outward", "boundary_inward", "missed_parts", "background",
    "offset_mean_px", "offset_std_px", "outward_share", "blobs_per_person",
)  # fmt: skip

FIRST_GUESS = MaskNoise(
    dilation_px=1.5, dilation_jitter_px=1.0, boundary_noise_px=1.5, boundary_sigma_px=4.0,
    thin_part_miss_rate=0.3, thin_part_px=2, blob_rate=0.2, blob_radius_px=(6.0, 20.0),
)  # fmt: skip
"""The defaults until 2026-12-05 (a first guess before BlazePose's masks were measured)."""

CANDIDATES: dict[str, MaskNoise] = {
    "defaults until 2026-12-05": FIRST_GUESS,
    "boundary noise 3": replace(FIRST_GUESS, boundary_noise_px=3.0),
    "boundary noise 3, blur 6": replace(FIRST_GUESS, boundary_noise_px=3.0, boundary_sigma_px=6.0),
    "boundary noise 2.5, jitter 1.5, blur 6": replace(
        FIRST_GUESS, boundary_noise_px=2.5, dilation_jitter_px=1.5, boundary_sigma_px=6.0
    ),
    "noise 2.5, jitter 1.5, blur 6, cells 24": replace(
        FIRST_GUESS, boundary_noise_px=2.5, dilation_jitter_px=1.5, boundary_sigma_px=6.0,
        noise_cells=24,
    ),
    "noise 2.5, jitter 1.5, blur 6, thin 0.5 x 3, blobs 0.5": replace(
        FIRST_GUESS, boundary_noise_px=2.5, dilation_jitter_px=1.5, boundary_sigma_px=6.0,
        thin_part_miss_rate=0.5, thin_part_px=3, blob_rate=0.5,
    ),
    "noise 2, jitter 1.2, blur 5, thin 0.5 x 3, blobs 0.5 of 4-14": replace(
        FIRST_GUESS, boundary_noise_px=2.0, dilation_jitter_px=1.2, boundary_sigma_px=5.0,
        thin_part_miss_rate=0.5, thin_part_px=3, blob_rate=0.5, blob_radius_px=(4.0, 14.0),
    ),
    "MaskNoise() since 2026-12-05: noise 2.2, dilation 0.5 ± 1.2, blur 5, thin 0.5 x 3, blobs "
    "0.5 of 4-14": MaskNoise(),
}  # fmt: skip


def exact_silhouettes(poses: Path | None, count: int, batch: int = 25) -> torch.Tensor:
    """``(count, 256, 256)`` bool silhouettes of ``val``-subject examples (before any erasing)."""
    config = SyntheticDataConfig(image_size=256)
    generator = SyntheticDataGenerator(pose_source(poses, "val"), config, "cpu")
    found = []
    for index, start in enumerate(range(0, count, batch)):
        rendered = generator.generate(min(batch, count - start), batch_seed(41, index))
        found.append(rendered.part_map >= 0)
    return torch.cat(found)


def measured_row(silhouettes: torch.Tensor, noise: MaskNoise, seed: int = 0) -> dict[str, float]:
    """The error summary of ``noise``'s masks against the exact ``silhouettes``."""
    known = torch.ones_like(silhouettes)
    masks = detector_like_masks(silhouettes, known, noise, torch.Generator().manual_seed(seed))
    people = []
    for mask, exact in zip(masks.numpy() >= 0.5, silhouettes.numpy(), strict=True):
        nothing = np.zeros_like(exact)
        people.append(compare_masks(mask, exact, nothing, np.ones_like(exact)))
    return summarise(people).row()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=Path, help="pose bank (its val split); else procedural")
    parser.add_argument("--count", type=int, default=200)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    silhouettes = exact_silhouettes(args.poses, args.count)
    rows = dict(BLAZEPOSE_TRAIN2017)
    for name, noise in CANDIDATES.items():
        rows[name] = measured_row(silhouettes, noise)
    print("| masks | " + " | ".join(COLUMNS) + " |")
    print("|---" * (len(COLUMNS) + 1) + "|")
    for name, row in rows.items():
        cells = [f"{row[c]:.3f}" if c in row else "" for c in COLUMNS]
        print(f"| {name} | " + " | ".join(cells) + " |")
    for name, noise in CANDIDATES.items():
        print(name, dataclasses.asdict(noise))


if __name__ == "__main__":
    main()

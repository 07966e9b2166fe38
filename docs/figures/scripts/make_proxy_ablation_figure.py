"""Render ``docs/figures/proxy_ablation.png`` and print the proxy ablation's table.

The paper's Table 1, rows 1-3: three small networks that differ only in what they see of the
image (a silhouette, the RGB crop, or the Canny edges; each with the 17 joint heatmaps;
``python -m hkpd.training.ablation --study proxies``). Left, what each one reads: one
synthetic test example (the training domain) and, below, the shipped CC0 photo (the real
domain; a photo has no silhouette until something segments it). Right, the 2D error of each
network's mode on the synthetic test set and on real photos (``coco_mini``, COCO's own person
masks as the silhouettes): the synthetic-to-real gap per proxy. The printed table also scores
each network with its image channels blanked (heatmaps only), which says how much it reads
its image proxy in each domain.

    python docs/figures/scripts/make_proxy_ablation_figure.py --poses poses.npz \\
        --coco ../shared/data/coco_mini
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch
from PIL import Image

from hkpd.evaluation.cli import evaluate_synthetic
from hkpd.evaluation.image_proxy_blanking import WithoutImageProxy
from hkpd.evaluation.real_photos import evaluate_photos, load_coco_people
from hkpd.evaluation.synthetic import evaluate_batches
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.poses import pose_source
from hkpd.prediction import Predictor
from hkpd.prediction.network_input import prepare_network_input
from hkpd.synthesis.generator import (
    SyntheticDataConfig,
    SyntheticDataGenerator,
    batch_seed,
)

FIGURE = Path(__file__).resolve().parents[1] / "proxy_ablation.png"
MODELS = Path(__file__).resolve().parents[3] / "assets" / "models" / "ablation"
PROXIES = {"silhouette": "silhouette", "rgb": "RGB", "edges": "edges"}
"""Image proxy -> label, in the paper's row order."""
EXAMPLE_SEED, EXAMPLE_INDEX = 2021, 3
"""The synthetic example shown: item 3 of the first test batch."""
SAMPLES = 25
"""Bodies sampled per synthetic example (hkpd-eval's default)."""


def _planes_picture(proxy: torch.Tensor) -> np.ndarray:
    """``(C + 17, S, S)`` proxy -> ``(S, S, 3)`` float picture of its image part, the joint
    heatmaps in red on top."""
    channels = proxy.shape[0] - 17
    image = proxy[:channels].permute(1, 2, 0).numpy()
    image = np.repeat(image, 3, axis=2) if channels == 1 else image.copy()
    heat = proxy[channels:].amax(0).numpy()
    image[..., 0] = np.maximum(image[..., 0], heat)
    image[..., 1:] *= 1 - 0.7 * heat[..., None]
    return image


def _synthetic_example(poses: Path | None, image_proxy: str, size: int) -> np.ndarray:
    generator = SyntheticDataGenerator(
        pose_source(poses, "test"), SyntheticDataConfig(image_size=size, image_proxy=image_proxy)
    )
    batch = generator.generate(EXAMPLE_INDEX + 1, batch_seed(EXAMPLE_SEED, 0)).batch
    return _planes_picture(batch.proxy[EXAMPLE_INDEX])


def _photo_input(predictor: Predictor, photo: Path) -> np.ndarray | None:
    if predictor.image_proxy == "silhouette":
        return None
    prepared = prepare_network_input(
        photo, predictor.detector, crop_size=predictor.crop_size, image_proxy=predictor.image_proxy
    )
    return _planes_picture(prepared.proxy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--poses", type=Path, help="pose bank (its test split); procedural if absent"
    )
    parser.add_argument("--coco", type=Path, required=True, help="coco_mini folder")
    parser.add_argument("--models", type=Path, default=MODELS, help="folder of proxy_*.pt")
    parser.add_argument("--count", type=int, default=1000, help="synthetic test examples")
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.set_grad_enabled(False)
    people = load_coco_people(args.coco)
    rows, pictures, person_errors = {}, {}, {}
    for proxy, label in PROXIES.items():
        checkpoint = args.models / f"proxy_{proxy}.pt"
        predictor = Predictor.from_pretrained(checkpoint, device="cpu")
        synthetic = evaluate_synthetic(
            checkpoint, args.poses, args.count, SAMPLES, torch.device("cpu")
        )
        person_errors[label] = []
        photos = evaluate_photos(
            predictor, people, show_progress=False, mode_errors=person_errors[label]
        )
        network, generator = network_and_generator(checkpoint, args.poses, "cpu")
        blind = WithoutImageProxy(network.eval())
        synthetic_blind = evaluate_batches(
            blind, fixed_batches(generator, args.count),
            generator.body, SAMPLES,
        )  # fmt: skip
        blind_predictor = Predictor(blind, "cpu", detector=predictor.detector)
        photos_blind = evaluate_photos(blind_predictor, people, show_progress=False)
        rows[label] = {
            "synthetic": synthetic,
            "photos": photos,
            "synthetic_blind": synthetic_blind,
            "photos_blind": photos_blind,
        }
        pictures[label] = (
            _synthetic_example(args.poses, proxy, predictor.crop_size),
            _photo_input(predictor, shipped_photo()),
        )
        predictor.close()
    print(
        "| image proxy + heatmaps | MPJPE-SC (mm) | MPJPE-PA (mm) | PVE-T-SC (mm) | 2D mode (px) "
        "| 2D samples (px) | coverage 50 / 90 | coco_mini: 2D mode (px) | box fraction | people "
        "| image blanked: synthetic 2D mode (px) | coco_mini 2D mode (px) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for label, row in rows.items():
        s, p = row["synthetic"], row["photos"]
        print(
            f"| {label} | {s['mpjpe_sc']:.1f} | {s['mpjpe_pa']:.1f} | {s['pve_t_sc']:.1f} | "
            f"{s['joint_error_2d_mode']:.2f} | {s['joint_error_2d_samples']:.2f} | "
            f"{s.get('pose_coverage_50', float('nan')):.2f} / "
            f"{s.get('pose_coverage_90', float('nan')):.2f} | "
            f"{p['joint_error_2d_mode']:.1f} | {p['joint_error_2d_mode_box_fraction']:.3f} | "
            f"{p['people']:.0f} | {row['synthetic_blind']['joint_error_2d_mode']:.2f} | "
            f"{row['photos_blind']['joint_error_2d_mode']:.1f} |"
        )
    edges = np.array(person_errors["edges"])
    for label, errors in person_errors.items():
        if label == "edges":
            continue
        difference = np.array(errors) - edges
        difference = difference[np.isfinite(difference)]
        standard_error = difference.std(ddof=1) / np.sqrt(difference.size)
        print(
            f"coco_mini, {label} minus edges, paired over {difference.size} people: "
            f"{difference.mean():+.2f} px (standard error {standard_error:.2f}), "
            f"worse for {(difference > 0).sum()} of them"
        )

    figure = plt.figure(figsize=(11.5, 4.4), dpi=110)
    grid = figure.add_gridspec(2, 5, width_ratios=[1, 1, 1, 0.15, 2.1])
    for column, (label, (synthetic, photo)) in enumerate(pictures.items()):
        for row, picture in enumerate((synthetic, photo)):
            axes = figure.add_subplot(grid[row, column])
            axes.set_xticks([])
            axes.set_yticks([])
            if picture is None:
                axes.set_facecolor("#eeeeee")
                axes.text(0.5, 0.5, "a photo has no\nsilhouette until\nsomething segments\nit "
                          "(coco_mini:\nCOCO's masks)", ha="center", va="center",
                          fontsize=8, transform=axes.transAxes)  # fmt: skip
            else:
                axes.imshow(np.clip(picture, 0, 1))
            if row == 0:
                axes.set_title(f"{label} + heatmaps", fontsize=9)
            if column == 0:
                axes.set_ylabel("synthetic" if row == 0 else "photo (CC0)", fontsize=9)
    bars = figure.add_subplot(grid[:, 4])
    labels = list(rows)
    positions = np.arange(len(labels))
    width = 0.38
    synthetic_errors = [rows[label]["synthetic"]["joint_error_2d_mode"] for label in labels]
    photo_errors = [rows[label]["photos"]["joint_error_2d_mode"] for label in labels]
    bars.bar(positions - width / 2, synthetic_errors, width, label="synthetic test set",
             color="#3b528b")  # fmt: skip
    bars.bar(positions + width / 2, photo_errors, width, label="real photos (coco_mini)",
             color="#e07b39")  # fmt: skip
    for position, synthetic, photo in zip(positions, synthetic_errors, photo_errors, strict=True):
        for offset, value in ((-width / 2, synthetic), (width / 2, photo)):
            bars.annotate(f"{value:.1f}", (position + offset, value), xytext=(0, 2),
                          textcoords="offset points", ha="center", fontsize=8)  # fmt: skip
    bars.set_xticks(positions, [f"{label}\n+ heatmaps" for label in labels], fontsize=8)
    bars.set_ylabel("2D joint error of the mode (px at 256)")
    bars.set_title("Network alone: synthetic vs real", fontsize=9)
    bars.set_ylim(0, max(photo_errors + synthetic_errors) * 1.2)
    bars.legend(fontsize=8, loc="upper left")
    bars.grid(axis="y", alpha=0.3)
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out)
    print(f"wrote {args.out}")
    Image.open(args.out).verify()


if __name__ == "__main__":
    main()

"""Float16 weights against float32 weights of the same network: the largest differences of the
posterior's parameters, on photos (the whole predictor: readings, keypoint fit) and on
synthetic proxies (the network alone).

Compares two checkpoints of one network, e.g. the float32 file shipped before issue 51
(``git show e005866:assets/models/hkpd_hierarchical.pt > float32.pt``) with the float16 one
shipped now, and prints one markdown table: per parameter of ``BodyDistribution``, the largest
absolute difference and the largest relative one (difference over the parameter's largest
magnitude), and the file sizes.

Usage: python benchmarks/bench_half_weights.py FLOAT32.pt FLOAT16.pt [--photos DIR]
       [--synthetic 64]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from hkpd.distributions import BodyDistribution
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.network.checkpoint import load_network
from hkpd.poses import ProceduralPosePrior
from hkpd.prediction import Predictor
from hkpd.prediction.image_input import IMAGE_SUFFIXES
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator

FIELDS = ("F", "shape_mean", "shape_std", "global_orient", "camera")


def differences(
    first: BodyDistribution, second: BodyDistribution
) -> dict[str, tuple[float, float]]:
    """Per field: the largest ``|a - b|`` and that over the field's largest ``|a|``."""
    found = {}
    for name, a, b in zip(FIELDS, first.tensors(), second.tensors(), strict=True):
        largest = float((a.double() - b.double()).abs().max())
        found[name] = (largest, largest / max(float(a.abs().max()), 1e-30))
    return found


def worst(into: dict[str, tuple[float, float]], more: dict[str, tuple[float, float]]) -> None:
    for name, (absolute, relative) in more.items():
        held = into.get(name, (0.0, 0.0))
        into[name] = (max(held[0], absolute), max(held[1], relative))


def photo_differences(
    paths: list[Path], first: Path, second: Path
) -> dict[str, tuple[float, float]]:
    """The evidence posteriors of every photo under both weights."""
    predictors = [Predictor.from_pretrained(str(path), device="cpu") for path in (first, second)]
    found: dict[str, tuple[float, float]] = {}
    with torch.no_grad():
        for path in paths:
            one, two = (predictor.predict(path).distribution for predictor in predictors)
            worst(found, differences(one, two))
    return found


def synthetic_differences(count: int, first: Path, second: Path) -> dict[str, tuple[float, float]]:
    """The network's own distributions for ``count`` synthetic proxies (procedural poses)."""
    networks = [load_network(path)[0] for path in (first, second)]
    size = networks[0].config.image_size
    generator = SyntheticDataGenerator(ProceduralPosePrior(), SyntheticDataConfig(image_size=size))
    proxies = generator.generate(count, seed=0).batch.proxy
    with torch.no_grad():
        return differences(*(network(proxies) for network in networks))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("float32", type=Path)
    parser.add_argument("float16", type=Path)
    parser.add_argument("--photos", type=Path, help="a folder of photos (default: the shipped one)")
    parser.add_argument("--synthetic", type=int, default=64)
    args = parser.parse_args()
    photos = [shipped_photo()]
    if args.photos is not None:
        photos += sorted(p for p in args.photos.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    started = time.perf_counter()
    on_photos = photo_differences(photos, args.float32, args.float16)
    on_synthetic = synthetic_differences(args.synthetic, args.float32, args.float16)
    sizes = [path.stat().st_size / 1e6 for path in (args.float32, args.float16)]
    print(f"# float16 vs float32 weights — {time.strftime('%Y-%m-%d %H:%M %Z')}")
    print(f"files: {args.float32.name} {sizes[0]:.1f} MB, {args.float16.name} {sizes[1]:.1f} MB; "
          f"{len(photos)} photos (predictor with evidence), {args.synthetic} synthetic proxies "
          f"(network alone); {time.perf_counter() - started:.0f} s")  # fmt: skip
    print()
    print("| parameter | photos: max abs / rel difference | synthetic: max abs / rel difference |")
    print("|---|---:|---:|")
    for name in FIELDS:
        (pa, pr), (sa, sr) = on_photos[name], on_synthetic[name]
        print(f"| {name} | {pa:.3g} / {pr:.3g} | {sa:.3g} / {sr:.3g} |")


if __name__ == "__main__":
    main()

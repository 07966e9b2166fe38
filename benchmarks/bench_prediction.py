"""Benchmark the photo front end of the predictor: loading, BlazePose detection, cropping.

Prints markdown tables (paste them into docs/prediction.md):

1. Per photo: ``load_image`` time, BlazePose detection time (median and best of the repeated
   calls on an already-warm graph) without and with segmentation, and with a ``bbox`` search.
2. Start-up: creating the ``Pose`` graph plus the first call (the first call is slower).
3. ``CropTransform.crop_image`` to 256 x 256 for a photo-sized box and for large boxes on a
   4096-pixel image (the area-averaging path), and ``apply_occluders``.
4. ``load_image`` of a 6000 x 4000 JPEG, which is downscaled to 4096 pixels.
5. ``prepare_network_input``: the whole front end (load, detect, crop, proxy) per photo.

Usage: python benchmarks/bench_prediction.py [--photos DIR] [--repeats 10]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from timing import call_times

from hkpd.prediction import (
    CropTransform,
    KeypointDetector,
    apply_occluders,
    load_image,
    prepare_network_input,
)

DEFAULT_PHOTOS = Path("/work/shared/data/demo_photos")


def timings(function: Callable[[], object], repeats: int) -> list[float]:
    """Wall-clock seconds of ``repeats`` calls."""
    return call_times(function, repeats, warmups=0)[0]


def ms(values: list[float]) -> str:
    """``median (best)`` in milliseconds."""
    return f"{statistics.median(values) * 1e3:.1f} ({min(values) * 1e3:.1f})"


def bench_detection(photos: list[Path], repeats: int) -> None:
    print("| photo | size | load_image ms | detect ms | detect + segm. ms | detect in bbox ms |")
    print("|---|---|---|---|---|---|")
    plain, segmenting = KeypointDetector(segmentation=False), KeypointDetector()
    all_plain, all_segmenting, all_bbox = [], [], []
    for photo in photos:
        loads = timings(lambda photo=photo: load_image(photo), repeats)
        loaded = load_image(photo)
        first = plain.detect(loaded)  # warm the graph on this photo
        segmenting.detect(loaded)
        detect = [plain.detect(loaded).seconds for _ in range(repeats)]
        segment = [segmenting.detect(loaded).seconds for _ in range(repeats)]
        in_box = [plain.detect(loaded, bbox=first.person_box).seconds for _ in range(repeats)]
        all_plain += detect
        all_segmenting += segment
        all_bbox += in_box
        width, height = loaded.original_size
        print(
            f"| {photo.name} | {width}x{height} | {ms(loads)} | {ms(detect)} | {ms(segment)} "
            f"| {ms(in_box)} |"
        )
    print(
        f"| **all photos** | | | **{ms(all_plain)}** | **{ms(all_segmenting)}** "
        f"| **{ms(all_bbox)}** |"
    )
    plain.close()
    segmenting.close()


def bench_startup(photo: Path) -> None:
    loaded = load_image(photo)
    start = time.perf_counter()
    detector = KeypointDetector()
    detection = detector.detect(loaded)
    total = time.perf_counter() - start
    detector.close()
    print("\n| start-up | ms |")
    print("|---|---|")
    print(f"| graph creation + first detect (incl. first call) | {total * 1e3:.0f} |")
    print(f"| of which the first `process` call | {detection.seconds * 1e3:.0f} |")


def bench_crops(photo: Path, repeats: int) -> None:
    loaded = load_image(photo)
    width, height = loaded.size
    rng = np.random.default_rng(0)
    big = cv2.resize(loaded.pixels, (4096, round(4096 * height / width)))
    cases = [
        ("photo-sized box", loaded.pixels, CropTransform((width / 2, height / 2), 0.8 * height)),
        ("4096-px image, 3000-px box", big, CropTransform((2048.0, 1300.0), 3000.0)),
        ("4096-px image, 300-px box", big, CropTransform((2048.0, 1300.0), 300.0)),
        ("box half outside the photo", loaded.pixels, CropTransform((0.0, 0.0), 0.8 * height)),
    ]
    print("\n| crop to 256 x 256 | ms, median (best) |")
    print("|---|---|")
    for name, image, crop in cases:
        print(f"| {name} | {ms(timings(lambda i=image, c=crop: c.crop_image(i), repeats * 5))} |")
    boxes = rng.uniform(0, min(width, height) / 2, (5, 2))
    boxes = np.concatenate([boxes, boxes + 80], 1)
    occlude = timings(lambda: apply_occluders(loaded, boxes), repeats * 5)
    print(f"| apply_occluders, 5 boxes on {width}x{height} | {ms(occlude)} |")


def bench_network_input(photos: list[Path], repeats: int) -> None:
    """The whole front end per photo: load, detect, crop, proxy (warm detector)."""
    with KeypointDetector() as detector:
        prepare_network_input(photos[0], detector)
        totals = []
        for photo in photos:
            totals += timings(lambda p=photo: prepare_network_input(p, detector), repeats)
    print("\n| prepare_network_input (load + detect + crop + proxy), all photos | ms |")
    print("|---|---|")
    print(f"| median (best) | {ms(totals)} |")


def bench_large_photo(photo: Path, repeats: int) -> None:
    """``load_image`` of a 6000 x 4000 JPEG (the demo photo upscaled), downscaled to 4096."""
    import tempfile

    pixels = cv2.resize(load_image(photo).pixels, (6000, 4000), interpolation=cv2.INTER_CUBIC)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "large.jpg"
        cv2.imwrite(str(path), pixels[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, 90])
        loads = timings(lambda: load_image(path), max(3, repeats // 2))
    print("\n| load_image of a 6000x4000 JPEG (decode + downscale to 4096x2731) | ms |")
    print("|---|---|")
    print(f"| median (best) | {ms(loads)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=Path, default=DEFAULT_PHOTOS)
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    photos = sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    if not photos:
        raise SystemExit(f"no .jpg/.png photos in {args.photos}")
    load = os.getloadavg()
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}, OpenCV {cv2.__version__}, "
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n"
    )
    bench_startup(photos[0])
    print()
    bench_detection(photos, args.repeats)
    bench_crops(photos[-1], args.repeats)
    bench_large_photo(photos[-1], args.repeats)
    bench_network_input(photos, args.repeats)


if __name__ == "__main__":
    main()

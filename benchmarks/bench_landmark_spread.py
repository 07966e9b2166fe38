"""What measuring the landmark spread costs ``KeypointDetector.detect`` (issue 51's quality
score; ``hkpd.prediction.detection.landmark_spread``).

For each photo: one warm-up call, then ``--repeats`` rounds, each timing ``detect`` once with
the spread measured (as shipped) and once with it skipped (the measurement replaced by a
constant), alternated so that both see the same load; the table gives each photo's median wall
times and their difference, and the median over photos. One interpreter thread per model
(``--threads``) and one torch thread, so the difference is the cost on one idle core.

Usage: python benchmarks/bench_landmark_spread.py DIR [--repeats 9] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import hkpd.prediction.detection.keypoint_detector as keypoint_detector
from hkpd.prediction import KeypointDetector, NoPersonFoundError, load_image
from hkpd.prediction.detection.blazepose import BlazePose
from hkpd.prediction.image_input import IMAGE_SUFFIXES


def timed(detector: KeypointDetector, photo, measured: bool) -> float:
    """Wall seconds of one ``detect`` with the spread ``measured`` or skipped."""
    shipped = keypoint_detector.landmark_spread
    if not measured:
        keypoint_detector.landmark_spread = lambda *arguments: 0.0
    try:
        start = time.perf_counter()
        detector.detect(photo)
        return time.perf_counter() - start
    finally:
        keypoint_detector.landmark_spread = shipped


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", type=Path)
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    detector = KeypointDetector(runner=BlazePose(0.5, args.threads, segmentation=True))
    paths = sorted(p for p in args.photos.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    print("| photo | size | detect ms, spread measured | skipped | cost ms |")
    print("|---|---|---|---|---|")
    costs = []
    for path in paths:
        photo = load_image(path)
        try:
            detector.detect(photo)
        except NoPersonFoundError:
            continue
        rounds = [(timed(detector, photo, True), timed(detector, photo, False))
                  for _ in range(args.repeats)]  # fmt: skip
        with_spread = statistics.median(r[0] for r in rounds) * 1000
        without = statistics.median(r[1] for r in rounds) * 1000
        costs.append(with_spread - without)
        size = "{}x{}".format(*photo.size)
        print(f"| {path.name} | {size} | {with_spread:.1f} | {without:.1f} | "
              f"{with_spread - without:+.1f} |")  # fmt: skip
    if costs:
        print(f"\nMedian cost over {len(costs)} photos: {statistics.median(costs):+.1f} ms")


if __name__ == "__main__":
    main()

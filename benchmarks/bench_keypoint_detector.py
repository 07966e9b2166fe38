"""Per-photo time of hkpd's BlazePose runner (``KeypointDetector.detect`` on loaded photos).

For each photo: one warm-up call, then ``--repeats`` timed calls of ``detect`` (photo already
decoded; letterbox, detector, decoding, NMS, landmark crop, landmark model, decoding); the table
gives the median over photos of each photo's median wall time, and the two models' share. On a
shared machine wall time grows with the load; the CPU time of a call (``detect`` CPU, all
threads) does not, and with ``--threads 1`` it is the wall time on an idle core.

``--no-segmentation`` times the runner without BlazePose's segmentation head (dropped at load;
the keypoints are identical), to measure what the person mask costs.

``--mediapipe`` times the legacy mediapipe solution the same way instead (where mediapipe is
installed; ``hkpd.prediction.detection.mediapipe_reference``).

Usage: python benchmarks/bench_keypoint_detector.py DIR [DIR ...] [--repeats 5] [--threads 1]
[--no-segmentation] [--mediapipe]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time
from pathlib import Path

from hkpd.prediction import KeypointDetector, NoPersonFoundError, load_image
from hkpd.prediction.detection.blazepose import BlazePose
from hkpd.prediction.image_input import IMAGE_SUFFIXES


def time_mediapipe(photos: list[Path], repeats: int) -> None:
    """Median wall and CPU ms of the legacy solution's call per photo (warm graph)."""
    from hkpd.prediction.detection.mediapipe_reference import MediapipePose

    pose = MediapipePose()
    wall, cpu = [], []
    for photo in photos:
        loaded = load_image(photo)
        pose.landmarks(loaded)
        calls, cpu_calls = [], []
        for _ in range(repeats):
            start, start_cpu = time.perf_counter(), time.process_time()
            pose.landmarks(loaded)
            calls.append(time.perf_counter() - start)
            cpu_calls.append(time.process_time() - start_cpu)
        wall.append(1e3 * statistics.median(calls))
        cpu.append(1e3 * statistics.median(cpu_calls))
    pose.close()
    print(f"mediapipe: wall {statistics.median(wall):.1f} ms median "
          f"(p90 {statistics.quantiles(wall, n=10)[-1]:.1f}), CPU {statistics.median(cpu):.1f} ms, "
          f"load average {os.getloadavg()[0]:.2f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1, help="interpreter threads per model")
    parser.add_argument(
        "--segmentation",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run the segmentation head (the person mask); --no-segmentation drops it",
    )
    parser.add_argument("--mediapipe", action="store_true", help="time the legacy solution")
    args = parser.parse_args()
    photos = [
        path
        for folder in args.folders
        for path in sorted(folder.iterdir())
        if path.suffix.lower() in IMAGE_SUFFIXES
    ]
    if args.mediapipe:
        time_mediapipe(photos, args.repeats)
        return
    runner = BlazePose(threads=args.threads, segmentation=args.segmentation)
    detector = KeypointDetector(segmentation=args.segmentation, runner=runner)
    print(f"{len(photos)} photos; {os.cpu_count()} CPUs; {args.threads} threads; "
          f"segmentation {'on' if args.segmentation else 'off'}; "
          f"load average before {os.getloadavg()[0]:.2f}")  # fmt: skip
    detect_ms, cpu_ms, find_ms, landmark_ms = [], [], [], []
    for photo in photos:
        loaded = load_image(photo)
        calls, cpu = [], []
        for repeat in range(args.repeats + 1):
            start, start_cpu = time.perf_counter(), time.process_time()
            with contextlib.suppress(NoPersonFoundError):
                detector.detect(loaded)
            if repeat:
                calls.append(time.perf_counter() - start)
                cpu.append(time.process_time() - start_cpu)
        detect_ms.append(1e3 * statistics.median(calls))
        cpu_ms.append(1e3 * statistics.median(cpu))
        start = time.perf_counter()
        people = runner.find_people(loaded.pixels)
        find_ms.append(1e3 * (time.perf_counter() - start))
        if people:
            start = time.perf_counter()
            runner.landmarks(loaded.pixels, people[0].region, args.segmentation)
            landmark_ms.append(1e3 * (time.perf_counter() - start))
    print("| step | median ms | p90 ms |")
    print("|---|---|---|")
    for name, values in [
        ("detect (whole runner)", detect_ms),
        ("detect CPU time (all threads)", cpu_ms),
        ("find_people (letterbox + detector + NMS)", find_ms),
        ("landmarks (crop + landmark model + decoding)", landmark_ms),
    ]:
        p90 = statistics.quantiles(values, n=10)[-1] if len(values) > 1 else values[0]
        print(f"| {name} | {statistics.median(values):.1f} | {p90:.1f} |")
    print(f"load average after {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()

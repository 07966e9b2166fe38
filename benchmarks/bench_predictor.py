"""Latency of the whole predictor with the model loaded: ``predict`` (detection + proxy +
network), then mode + 100 samples + per-vertex uncertainty.

Usage: python benchmarks/bench_predictor.py [--model CKPT] [--photos DIR] [--repeats 5]
       [--threads 2]

Without ``--photos`` it uses the explorer's built-in demo photo (rendered by hkpd itself).
Prints a markdown table; results are recorded in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import torch

from hkpd.prediction import Predictor


def demo_photo():
    from hkpd.explorer.demo_scene import render_demo_scene

    return render_demo_scene().image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--model", help="checkpoint (default: the shipped model)")
    parser.add_argument("--photos", type=Path, help="folder of photos")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    predictor = Predictor.from_pretrained(args.model, device="cpu")
    if args.photos:
        photos = sorted(p for p in args.photos.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    else:
        photos = [demo_photo()]
    predictor.predict(photos[0])  # warm up the detector graph and the network
    predict_times, sample_times = [], []
    for photo in photos:
        for _ in range(args.repeats):
            start = time.perf_counter()
            posterior = predictor.predict(photo)
            middle = time.perf_counter()
            posterior.mode()
            posterior.vertex_uncertainty(100)
            end = time.perf_counter()
            predict_times.append(middle - start)
            sample_times.append(end - middle)
    load = os.getloadavg()[0]
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load {load:.1f}, torch "
          f"{torch.__version__}, threads {args.threads}, network input "
          f"{predictor.crop_size} px, {len(photos)} photo(s) x {args.repeats}")  # fmt: skip
    print()
    print("| step | median ms | best ms | target |")
    print("|---|---|---|---|")
    print(f"| predict: detection + proxy + network | {statistics.median(predict_times) * 1e3:.0f} "
          f"| {min(predict_times) * 1e3:.0f} | <= 200 |")  # fmt: skip
    print(f"| mode + 100 samples + vertex uncertainty | "
          f"{statistics.median(sample_times) * 1e3:.0f} | {min(sample_times) * 1e3:.0f} "
          f"| <= 100 |")  # fmt: skip


if __name__ == "__main__":
    main()

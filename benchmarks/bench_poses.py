"""Benchmark the pose stage: BVH parsing, retargeting, and sampling from the two pose sources.

Usage: python benchmarks/bench_poses.py [--bank /tmp/hkpd_poses/cmu_poses.npz]
       [--bvh /work/shared/data/cmu_mocap/daz_bvh_Przestr/02_01.bvh] [--repeats 7]

Prints a table of median and best wall-clock times (the machine is shared, so medians are noisy).
Parts whose inputs are missing (no bank file, no BVH file) are skipped.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import torch
from timing import median_and_best

from hkpd.poses import PoseBank, ProceduralPosePrior, load_bvh, retarget


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bank", default="/tmp/hkpd_poses/cmu_poses.npz")
    parser.add_argument("--bvh", default="/work/shared/data/cmu_mocap/daz_bvh_Przestr/02_01.bvh")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument(
        "--threads", type=int, nargs="+", default=[1, torch.get_num_threads()],
        help="torch intra-op thread counts to measure with (default: 1 and the default)",
    )  # fmt: skip
    args = parser.parse_args()
    torch.set_grad_enabled(False)
    for threads in dict.fromkeys(args.threads):
        torch.set_num_threads(threads)
        run(args)


def run(args: argparse.Namespace) -> None:
    rows: list[tuple[str, str, float, float]] = []
    if Path(args.bvh).is_file():
        motion = load_bvh(args.bvh)
        frames = f"{motion.num_frames} frames"
        rows.append(
            ("parse BVH", frames, *median_and_best(lambda: load_bvh(args.bvh), args.repeats))
        )
        rows.append(
            ("retarget clip", frames, *median_and_best(lambda: retarget(motion), args.repeats))
        )
    sources: list[tuple[str, object]] = [("ProceduralPosePrior.sample", ProceduralPosePrior())]
    if Path(args.bank).is_file():
        rows.append(("PoseBank.load train", args.bank, *median_and_best(
            lambda: PoseBank.load(args.bank), args.repeats)))  # fmt: skip
        sources.append(("PoseBank.sample", PoseBank.load(args.bank)))
    for name, source in sources:
        for count in (64, 1024):
            generator = torch.Generator().manual_seed(0)
            rows.append(
                (name, f"count={count}", *median_and_best(
                    lambda s=source, c=count, g=generator: s.sample(c, g), args.repeats))
            )  # fmt: skip
    print(f"threads={torch.get_num_threads()} load={os.getloadavg()[0]:.1f}")
    print(f"{'operation':<28} {'input':<36} {'median ms':>10} {'best ms':>9}")
    for name, detail, median, best in rows:
        print(f"{name:<28} {detail[-36:]:<36} {1e3 * median:>10.2f} {1e3 * best:>9.2f}")


if __name__ == "__main__":
    main()

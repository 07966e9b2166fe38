"""Throughput of the synthetic data generator (samples/s), with a per-stage breakdown.

Usage: python benchmarks/bench_synthesis.py [--batch-sizes 16 32 64] [--image-size 256]
       [--poses poses.npz] [--device cpu] [--threads 2] [--repeats 5] [--workers 1 2]
       [--no-keep-memory]

Like training, it first asks glibc to keep freed memory (:mod:`hkpd.cpu_allocator`);
``--no-keep-memory`` measures the default allocator instead.

Prints a markdown table; results are recorded in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time

import numpy as np
import torch
from timing import call_times

from hkpd.cpu_allocator import keep_freed_memory
from hkpd.poses import pose_source
from hkpd.proxy import build_proxy_batch
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator, batch_seed


def timed(function, repeats: int, synchronise) -> list[float]:
    """Wall seconds of ``repeats`` calls (warm-ups are done by the caller)."""
    return call_times(function, repeats, warmups=0, synchronise=synchronise)[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--batch-sizes", type=int, nargs="+", default=[16, 32, 64])
    parser.add_argument("--image-size", type=int, default=256)
    parser.add_argument("--poses", help="pose bank .npz (default: procedural prior)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--workers",
        type=int,
        nargs="*",
        default=[],
        help="also time the multi-process stream (ParallelBatches) with these worker counts",
    )
    parser.add_argument(
        "--no-keep-memory",
        action="store_true",
        help="leave glibc's allocator as it is (large blocks mapped and unmapped every batch)",
    )
    args = parser.parse_args()
    kept = False if args.no_keep_memory else keep_freed_memory()
    torch.set_num_threads(args.threads)
    device = torch.device(args.device)
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    poses = pose_source(args.poses, "train")
    generator = SyntheticDataGenerator(
        poses, SyntheticDataConfig(image_size=args.image_size), device=device
    )
    generator.generate(4, 0)  # warm up
    renderer = generator.renderer.render
    print(f"machine: {platform.processor() or platform.machine()}, torch "
          f"{torch.__version__}, threads {torch.get_num_threads()}, device {device}, "
          f"{args.image_size} px, poses {'bank' if args.poses else 'procedural'}, "
          f"freed memory kept: {kept}")  # fmt: skip
    print()
    print("| B | whole batch: median (best) ms | samples/s (median) | body model ms | render ms "
          "| proxy (Canny + heatmaps) ms |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for size in args.batch_sizes:
        seeds = iter(range(10_000))
        whole = timed(lambda s=size, n=seeds: generator.generate(s, batch_seed(1, next(n))),
                      args.repeats, sync)  # fmt: skip
        rendered = generator.generate(size, 123)
        batch = rendered.batch
        body_times = timed(
            lambda b=batch: generator.body(b.betas, b.body_pose, b.global_orient), args.repeats,
            sync,
        )  # fmt: skip
        vertices = generator.body(batch.betas, batch.body_pose, batch.global_orient).vertices
        vertices = vertices + torch.tensor([0.0, 0.0, 3.0], device=device)
        colours = generator.textures.sample(size, torch.Generator().manual_seed(0), device)
        from hkpd.rendering import sample_lighting

        lighting = sample_lighting(size, torch.Generator().manual_seed(0), device)
        focal = torch.full((size,), 300.0 * args.image_size / 256, device=device)
        render_times = timed(
            lambda v=vertices, f=focal, c=colours, li=lighting: renderer(v, f, c, li),
            args.repeats,
            sync,
        )
        images = np.ascontiguousarray(rendered.images)
        proxy_times = timed(
            lambda i=images, b=batch: build_proxy_batch(i, b.keypoints2d, b.visible, device),
            args.repeats, sync,
        )  # fmt: skip
        median = statistics.median(whole)
        print(
            f"| {size} | {median * 1e3:.0f} ({min(whole) * 1e3:.0f}) | {size / median:.0f} | "
            f"{statistics.median(body_times) * 1e3:.0f} | "
            f"{statistics.median(render_times) * 1e3:.0f} | "
            f"{statistics.median(proxy_times) * 1e3:.0f} |"
        )
    if args.workers:
        time_parallel(args)


def time_parallel(args) -> None:
    """Samples/s of :class:`ParallelBatches` (one single-threaded generator per process)."""
    from hkpd.synthesis.parallel import GeneratorSpec, ParallelBatches

    spec = GeneratorSpec(poses=args.poses, config=SyntheticDataConfig(image_size=args.image_size))
    torch.set_num_threads(1)  # the consumer only draws heatmaps; the cores go to the workers
    print()
    print("| workers | B | samples/s (stream, after warm-up; consumer 1 thread) |")
    print("|---|---|---|")
    for workers in args.workers:
        for size in args.batch_sizes:
            with ParallelBatches(
                spec, size, seed=1, workers=workers, keep_memory=not args.no_keep_memory
            ) as stream:
                for _ in range(2 * workers):  # warm-up: start the processes, fill the queues
                    next(stream)
                count = max(4, args.repeats) * workers
                start = time.perf_counter()
                for _ in range(count):
                    next(stream)
                rate = count * size / (time.perf_counter() - start)
            print(f"| {workers} | {size} | {rate:.0f} |")


if __name__ == "__main__":
    main()

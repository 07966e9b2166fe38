"""Training throughput of ``hkpd-train`` with 1, 2, ... processes under torchrun (DDP).

Each row is one ``torchrun --standalone --nproc-per-node P`` run of ``hkpd-train`` for
``--steps`` steps; its samples per second (all processes together, as ``train.csv`` logs them)
is the median over the logged windows after the first (start-up, first batches)::

    python benchmarks/bench_training_ddp.py                       # CPU: 1 and 2 processes
    python benchmarks/bench_training_ddp.py --device cuda --processes 1 2 4 8

On the CPU, torchrun gives each of several processes one thread (``OMP_NUM_THREADS=1``); the
single process gets ``--threads`` (default 1 as well). Every process also renders its batches
in a background thread, so one process already keeps two cores busy.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def run_training(processes: int, arguments: argparse.Namespace, out: Path) -> list[float]:
    """Samples per second of each logged window of one run (all processes together)."""
    command = [
        sys.executable, "-m", "torch.distributed.run", "--standalone",
        f"--nproc-per-node={processes}", "-m", "hkpd.training.cli", f"--out={out}",
        f"--device={arguments.device}", f"--steps={arguments.steps}",
        f"--batch-size={arguments.batch_size}", f"--image-size={arguments.image_size}",
        f"--backbone-base-width={arguments.width}", f"--log-every={arguments.log_every}",
        "--val-every=0", "--val-size=2", "--checkpoint-every=100000", "--quiet",
        "--samples-loss-from=0", "--joints3d-loss-from=0",
    ]  # fmt: skip
    environment = dict(os.environ)
    if processes == 1 and arguments.device == "cpu":
        environment["OMP_NUM_THREADS"] = str(arguments.threads)
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{processes} processes failed:\n{done.stderr[-3000:]}")
    with (out / "train.csv").open() as handle:
        return [float(row["samples_per_second"]) for row in csv.DictReader(handle)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--processes", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--threads", type=int, default=1, help="of a single process (CPU)")
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--log-every", type=int, default=5)
    parser.add_argument("--batch-size", type=int, default=8, help="per process")
    parser.add_argument("--image-size", type=int, default=128)
    parser.add_argument("--width", type=int, default=16, help="ResNet-18 base width")
    arguments = parser.parse_args()
    print(
        f"hkpd-train on {arguments.device}: {arguments.image_size} px, width {arguments.width}, "
        f"batch {arguments.batch_size} per process, {arguments.steps} steps "
        f"(median of the windows of {arguments.log_every} steps after the first)\n"
    )
    print("| processes | threads each | global batch | samples/s | steps/s | vs 1 process |")
    print("|---:|---:|---:|---:|---:|---:|")
    first = None
    with tempfile.TemporaryDirectory() as folder:
        for processes in arguments.processes:
            windows = run_training(processes, arguments, Path(folder) / f"p{processes}")
            rate = statistics.median(windows[1:] or windows)
            first = rate if first is None else first
            threads = arguments.threads if processes == 1 else 1
            if arguments.device != "cpu":
                threads = "-"
            global_batch = processes * arguments.batch_size
            print(
                f"| {processes} | {threads} | {global_batch} | {rate:.1f} | "
                f"{rate / global_batch:.2f} | {rate / first:.2f}x |"
            )


if __name__ == "__main__":
    main()

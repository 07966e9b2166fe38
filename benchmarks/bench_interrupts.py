"""Ctrl-C at random moments: ``hkpd-predict`` on a folder, one SIGINT per run at a uniformly
random time, every run checked for exit status 130, one "interrupted" line on stderr, no
traceback and no partial output (no ``.NAME.partial`` folder; every folder left is complete).

The folder holds copies of the shipped CC0 photo; the shipped model. The time range defaults to
one uninterrupted run's wall time (measured first), so the signals land during the imports,
the model load and the photos in proportion to how long each takes.

Usage: python benchmarks/bench_interrupts.py [--runs 20] [--photos 3] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hkpd.explorer.demo_photo import shipped_photo

LAUNCH = (
    "import sys; from hkpd.interrupts import run_command; "
    "sys.exit(run_command(sys.argv[1], sys.argv[2:]))"
)


def run(photos: Path, out: Path, after_s: float | None) -> tuple[int, str, float]:
    """hkpd-predict on ``photos``, SIGINT after ``after_s`` (None: none); status, stderr, s."""
    command = [sys.executable, "-c", LAUNCH, "hkpd-predict", str(photos), "--out", str(out),
               "--samples", "1", "--uncertainty-samples", "10"]  # fmt: skip
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if after_s is not None:
        try:
            process.wait(timeout=after_s)
        except subprocess.TimeoutExpired:
            process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=300)
    return process.returncode, err.decode(errors="replace"), time.perf_counter() - start


def problems(status: int, stderr: str, out: Path, interrupted: bool) -> list[str]:
    """What is wrong with one run (empty: all as it should be)."""
    found = []
    lines = [line for line in stderr.replace("\r", "\n").splitlines() if "interrupted" in line]
    if interrupted and status != 130:
        found.append(f"exit {status}")
    if interrupted and len(lines) != 1:
        found.append(f"{len(lines)} 'interrupted' lines")
    if "Traceback" in stderr:
        found.append("traceback")
    left = sorted(out.iterdir()) if out.exists() else []
    found += [f"partial {p.name}" for p in left if p.name.startswith(".")]
    found += [
        f"incomplete {p.name}"
        for p in left
        if not p.name.startswith(".") and not (p / "summary.json").is_file()
    ]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--photos", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as temp:
        photos = Path(temp) / "photos"
        photos.mkdir()
        for index in range(args.photos):
            shutil.copy(shipped_photo(), photos / f"photo_{index}.jpg")
        status, stderr, full_s = run(photos, Path(temp) / "full", None)
        assert status == 0, stderr
        print(f"# hkpd-predict Ctrl-C benchmark — {time.strftime('%Y-%m-%d %H:%M %Z')}")
        load = os.getloadavg()[0]
        print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load average {load:.1f}; "
              f"{args.photos} photos, uninterrupted {full_s:.1f} s")  # fmt: skip
        print()
        print("| run | SIGINT at s | exit | stopped after s | folders left | problems |")
        print("|---:|---:|---:|---:|---:|---|")
        failures = 0
        for index in range(args.runs):
            out = Path(temp) / f"out_{index}"
            after_s = float(rng.uniform(0.2, full_s))
            status, stderr, seconds = run(photos, out, after_s)
            finished = seconds < after_s  # it ended before the signal was due
            found = problems(status, stderr, out, interrupted=not finished)
            failures += bool(found)
            left = len(list(out.iterdir())) if out.exists() else 0
            print(f"| {index} | {after_s:.1f} | {status} | {seconds:.1f} | {left} | "
                  f"{', '.join(found) or ('none (finished first)' if finished else 'none')} |",
                  flush=True)  # fmt: skip
        print()
        print(f"{args.runs - failures} of {args.runs} runs as they should be")


if __name__ == "__main__":
    main()

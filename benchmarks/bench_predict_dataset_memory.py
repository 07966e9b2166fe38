"""Memory of each process over a long ``hkpd-predict`` run under torchrun: does it stay flat?

One ``torchrun --standalone --nproc_per_node P --no-python hkpd-predict`` run over ``--photos``
photos (the demo photos, or the shipped photo, copied under different names) plus one damaged
file, with the shipped model and the default outputs. Every ``--every`` seconds the script reads
each process's resident memory (``VmRSS`` in ``/proc``) and how many photos the run has
finished (result folders and recorded failures, from the part files); it prints each rank's
memory at a few points of the run, its growth from a quarter of the way to the end (after
warm-up), and the index's statuses::

    python benchmarks/bench_predict_dataset_memory.py                  # 1000 photos, 2 processes
    python benchmarks/bench_predict_dataset_memory.py --photos 200 --extra --samples 2
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_predict_sharded import load_average, predict_command, prepare_photos


def children(parent: int) -> list[int]:
    """The process ids whose parent is ``parent``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == parent:
            found.append(int(entry.name))
    return found


def rank_of(pid: int) -> int | None:
    """The ``RANK`` in the environment of process ``pid`` (None when it has none)."""
    try:
        variables = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    except OSError:
        return None
    for variable in variables:
        if variable.startswith(b"RANK="):
            return int(variable[len(b"RANK=") :])
    return None


def resident_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def photos_finished(out: Path) -> int:
    """Photos the run has recorded so far (lines of its part files, or of the index)."""
    parts = list((out / ".hkpd-predict").glob("part-*.jsonl"))
    files = parts or [out / "index.jsonl"]
    total = 0
    for path in files:
        try:
            total += path.read_bytes().count(b"\n")
        except OSError:
            continue
    return total


def watch(process: subprocess.Popen, out: Path, every: float) -> list[tuple[float, int, dict]]:
    """``(seconds, photos finished, {rank: RSS MB})`` every ``every`` seconds until the end."""
    samples = []
    started = time.perf_counter()
    ranks: dict[int, int] = {}
    while process.poll() is None:
        for pid in children(process.pid):
            rank = rank_of(pid)
            if rank is not None:
                ranks[rank] = pid
        memory = {rank: resident_mb(pid) for rank, pid in ranks.items()}
        memory = {rank: mb for rank, mb in memory.items() if mb is not None}
        if memory:
            samples.append((time.perf_counter() - started, photos_finished(out), memory))
        time.sleep(every)
    return samples


def report(samples: list[tuple[float, int, dict]], total: int) -> None:
    """Each rank's RSS at fractions of the run, and its growth after the first quarter."""
    ranks = sorted({rank for _, _, memory in samples for rank in memory})
    print("| photos done | seconds | " + " | ".join(f"rank {r} RSS MB" for r in ranks) + " |")
    print("|---|---|" + "---|" * len(ranks))
    for fraction in (0.05, 0.25, 0.5, 0.75, 1.0):
        wanted = fraction * total
        chosen = min(samples, key=lambda sample: abs(sample[1] - wanted))
        row = " | ".join(f"{chosen[2].get(r, float('nan')):.0f}" for r in ranks)
        print(f"| {chosen[1]} | {chosen[0]:.0f} | {row} |")
    quarter = [sample for sample in samples if sample[1] >= total / 4]
    for rank in ranks:
        values = [(done, memory[rank]) for _, done, memory in quarter if rank in memory]
        if len(values) < 2 or values[-1][0] == values[0][0]:
            continue
        (first_done, first_mb), (last_done, last_mb) = values[0], values[-1]
        peak = max(mb for _, mb in values)
        slope = 100.0 * (last_mb - first_mb) / (last_done - first_done)
        print(f"rank {rank}: {first_mb:.0f} MB at {first_done} photos -> {last_mb:.0f} MB at "
              f"{last_done} (peak {peak:.0f}): {slope:+.2f} MB per 100 photos")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=1000)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--every", type=float, default=2.0, help="seconds between samples")
    parser.add_argument("--extra", nargs=argparse.REMAINDER, default=[],
                        help="further hkpd-predict options (last)")  # fmt: skip
    arguments = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_predict_memory_"))
    try:
        prepare_photos(work / "photos", arguments.photos)
        (work / "photos" / "damaged.jpg").write_bytes(b"\xff\xd8\xff\xe0 cut short" * 30)
        out = work / "out"
        print(f"hkpd-predict under torchrun, {arguments.processes} processes, "
              f"{arguments.photos} photos + 1 damaged, options {arguments.extra or 'default'}, "
              f"load before {load_average()}", flush=True)  # fmt: skip
        command = predict_command(arguments.processes, work / "photos", out, arguments.extra)
        with (work / "log.txt").open("w") as log:
            process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT,
                                       env=dict(os.environ, OMP_NUM_THREADS="1"))  # fmt: skip
            samples = watch(process, out, arguments.every)
        if process.returncode != 0:
            sys.exit(f"the run failed:\n{(work / 'log.txt').read_text()[-3000:]}")
        report(samples, arguments.photos + 1)
        records = [json.loads(line) for line in (out / "index.jsonl").read_text().splitlines()]
        statuses = collections.Counter(
            record["status"] if record["status"] in ("ok", "no person") else "error: ..."
            for record in records
        )
        leftovers = sorted(path.name for path in out.iterdir() if path.name.startswith("."))
        print(f"index: {len(records)} lines, {dict(statuses)}; hidden leftovers: {leftovers}; "
              f"load after {load_average()}")  # fmt: skip
        print((work / "log.txt").read_text().strip().splitlines()[-1])
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

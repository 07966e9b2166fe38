"""Photos per minute of ``hkpd-predict`` alone and split over processes under torchrun, and
whether the split runs write the same numbers.

Each row is one run over the same ``--photos`` photos (the demo photos under
``/work/shared/data/demo_photos``, or the shipped photo, copied under different names), with
the shipped model and the default outputs (10 samples, ply + npz, overview)::

    python benchmarks/bench_predict_sharded.py                    # 1 and 2 processes, 24 photos
    python benchmarks/bench_predict_sharded.py --processes 1 2 1 2 --photos 48

One process runs with ``OMP_NUM_THREADS=1``; under torchrun each of P processes gets the
machine's cores // P threads (one each on a 2-core machine). "steady" counts the photos
finished after every process finished its first one (model loading and the first photo's
warm-up left out), over the time from then to the last; "overall" is photos over the
command's whole wall time (torchrun, imports and model loading included); "CPU s/photo" is the
CPU time of all its processes (user + system, start-up included) per photo, which other jobs
on a shared machine disturb far less than the wall time. "same as 1" compares
every array of every photo's ``prediction.npz`` with the first one-process run's, bit for bit.
The load average is printed: the machine is shared.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

import numpy as np

DEMO_PHOTOS = Path("/work/shared/data/demo_photos")


def prepare_photos(folder: Path, count: int) -> list[Path]:
    """``count`` photos in ``folder``: the demo photos (or the shipped one) repeated under new
    names."""
    sources = sorted(DEMO_PHOTOS.glob("*.jpg")) if DEMO_PHOTOS.is_dir() else []
    if not sources:
        from hkpd.explorer.demo_photo import shipped_photo

        sources = [Path(shipped_photo())]
    folder.mkdir(parents=True, exist_ok=True)
    photos = []
    for index, source in zip(range(count), itertools.cycle(sources), strict=False):
        photo = folder / f"photo_{index:04d}_{source.name}"
        shutil.copyfile(source, photo)
        photos.append(photo)
    return photos


def predict_command(processes: int, photos: Path, out: Path, extra: list[str]) -> list[str]:
    """The command of one run: ``hkpd-predict`` alone, or under torchrun with ``processes``."""
    program = str(Path(sys.executable).parent / "hkpd-predict")
    arguments = [str(photos), "--out", str(out), *extra]
    if processes == 1:
        return [program, *arguments]
    return [sys.executable, "-m", "torch.distributed.run", "--standalone",
            f"--nproc_per_node={processes}", "--no-python", program, *arguments]  # fmt: skip


def run_once(processes: int, photos: Path, out: Path, extra: list[str]) -> dict:
    """Run and time one command; its index's finish times give the steady rate."""
    environment = dict(os.environ, OMP_NUM_THREADS="1")
    cpu_before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(
        predict_command(processes, photos, out, extra),
        capture_output=True, text=True, env=environment, check=False,
    )  # fmt: skip
    wall = time.perf_counter() - started
    cpu_after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = sum(getattr(cpu_after, f) - getattr(cpu_before, f) for f in ("ru_utime", "ru_stime"))
    if done.returncode != 0:
        raise RuntimeError(f"{processes} process(es) failed:\n{done.stderr[-3000:]}")
    records = [json.loads(line) for line in (out / "index.jsonl").read_text().splitlines()]
    return {"wall": wall, "cpu": cpu, "records": records}


def steady_rate(records: list[dict]) -> float:
    """Photos per minute finished after every rank finished its first photo, to the last."""
    times: dict[int, list[float]] = {}
    for record in records:
        moment = datetime.fromisoformat(record["finished"]).timestamp()
        times.setdefault(record["rank"], []).append(moment)
    start = max(min(moments) for moments in times.values())
    later = [moment for moments in times.values() for moment in moments if moment > start]
    if not later:
        return float("nan")
    return 60.0 * len(later) / (max(later) - start)


def same_arrays(reference: Path, other: Path, names: list[str]) -> tuple[int, int]:
    """(photos whose prediction.npz arrays are all bit-identical, photos compared); the
    photos that differ are printed with the arrays that do."""
    identical = 0
    for name in names:
        one = np.load(reference / name / "prediction.npz")
        two = np.load(other / name / "prediction.npz")
        differ = [key for key in one.files if key not in two.files or
                  one[key].tobytes() != two[key].tobytes()]  # fmt: skip
        identical += not differ and sorted(one.files) == sorted(two.files)
        if differ:
            print(f"  {name}: {len(differ)} arrays differ: {', '.join(differ[:6])}")
    return identical, len(names)


def load_average() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--photos", type=int, default=24)
    parser.add_argument("--extra", nargs=argparse.REMAINDER, default=[],
                        help="further hkpd-predict options (last)")  # fmt: skip
    arguments = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_predict_sharded_"))
    try:
        photos = prepare_photos(work / "photos", arguments.photos)
        names = [photo.stem for photo in photos]
        print(f"hkpd-predict, {len(photos)} photos, cores {os.cpu_count()}, "
              f"load before {load_average()}")  # fmt: skip
        print("| processes | steady photos/min | overall photos/min | wall s | CPU s/photo | "
              "same as 1 | load |")  # fmt: skip
        print("|---|---|---|---|---|---|---|")
        reference = None
        for run, processes in enumerate(arguments.processes):
            out = work / f"out_{run}_{processes}"
            result = run_once(processes, work / "photos", out, arguments.extra)
            if reference is None and processes == 1:
                reference = out
            same = "-" if reference is None else "{}/{}".format(*same_arrays(reference, out, names))
            overall = 60.0 * len(photos) / result["wall"]
            print(f"| {processes} | {steady_rate(result['records']):.1f} | {overall:.1f} | "
                  f"{result['wall']:.1f} | {result['cpu'] / len(photos):.2f} | {same} | "
                  f"{load_average()} |", flush=True)  # fmt: skip
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

"""Time of one forward of each graph model on hkpd's runtime (``hkpd.model_runtime``).

For each model: load time (read, check, prepare; sha256 checks included for shipped models on
their first load), then ``--repeats`` timed ``run`` calls after one warm-up, on a deterministic
random input of the model's shape (faceres also in batches of 8: the time per face). The table
gives median and best wall time and the median process CPU time (all threads), with the
machine's load average (``os.getloadavg``) before and after, since this machine is shared.

Usage: python benchmarks/bench_model_runtime.py [--threads 1] [--repeats 10] [--device cpu]
[--extra-dir DIR --extra centernet]   (e.g. DIR = the unpacked npm package's models folder)
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import torch
from timing import call_times

from hkpd.model_runtime import GraphModel
from hkpd.model_runtime.shipped import HUMAN_MODELS, load_human_model

FREE_SIDE = 256
"""Size of a free (-1) input axis other than the batch (movenet-multipose's image side)."""


def _example_inputs(model: GraphModel, batch: int) -> dict[str, torch.Tensor]:
    """Each input of ``model`` as a deterministic random tensor (a free batch -> ``batch``,
    other free sizes -> FREE_SIDE):
    floats in 0..1 (x255 for NHWC 3-channel images), ints in 0..255."""
    generator = torch.Generator().manual_seed(0)
    inputs = {}
    for name, spec in model.inputs.items():
        shape = [
            size if size != -1 else batch if axis == 0 else FREE_SIDE
            for axis, size in enumerate(spec.shape or ())
        ]
        values = torch.rand(shape, generator=generator)
        if spec.dtype == "DT_INT32":
            inputs[name] = (values * 255).to(torch.int32)
        else:
            inputs[name] = values * 255 if shape[-1:] == [3] else values
    return inputs


def _row(label: str, load_s: float, walls: list[float], cpus: list[float], per: int) -> str:
    median = sorted(walls)[len(walls) // 2] / per
    best = min(walls) / per
    cpu = sorted(cpus)[len(cpus) // 2] / per
    times = " | ".join(f"{seconds * 1e3:.1f}" for seconds in (median, best, cpu))
    return f"| {label} | {load_s * 1e3:.0f} | {times} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--extra-dir", type=Path, help="folder of more model.json files")
    parser.add_argument("--extra", nargs="*", default=[], help="their names (e.g. centernet)")
    arguments = parser.parse_args()
    torch.set_num_threads(arguments.threads)
    device = torch.device(arguments.device)
    synchronise = torch.cuda.synchronize if device.type == "cuda" else None
    cases = [(name, lambda n=name: load_human_model(n), 1) for name in HUMAN_MODELS]
    cases.insert(1, ("faceres (batch 8, per face)", lambda: load_human_model("faceres"), 8))
    cases += [
        (name, lambda n=name: GraphModel.load(arguments.extra_dir / f"{n}.json"), 1)
        for name in arguments.extra
    ]
    load_before = os.getloadavg()[0]
    print(f"threads {arguments.threads}, device {device}, torch {torch.__version__}")
    print("| model | load ms | median ms | best ms | CPU ms |\n|---|---|---|---|---|")
    for label, load, batch in cases:
        start = time.perf_counter()
        model = load().to(device)
        load_s = time.perf_counter() - start
        inputs = {k: v.to(device) for k, v in _example_inputs(model, batch).items()}
        walls, cpus = call_times(
            lambda m=model, x=inputs: m.run(x), arguments.repeats, synchronise=synchronise
        )
        print(_row(label, load_s, walls, cpus, batch))
    print(f"load average (1 min): {load_before:.2f} before, {os.getloadavg()[0]:.2f} after")


if __name__ == "__main__":
    main()

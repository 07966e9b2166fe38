"""Peak memory of ``BodyPosterior.vertex_uncertainty(n)`` for large n (bounded by chunking).

Usage: python benchmarks/bench_uncertainty_memory.py [--counts 100 2000 20000]

Each count runs in a fresh process and reports its peak resident set (ru_maxrss) minus the
baseline after loading the model and building the posterior. Prints a markdown table;
results are recorded in docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys

CHILD = """
import resource, time, torch
from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.posterior import BodyPosterior
torch.set_num_threads(2)
distribution = BodyDistribution(
    30.0 * torch.eye(3).expand(23, 3, 3).clone(), torch.zeros(10), torch.ones(10) * 0.3,
    FRONTAL_GLOBAL_ORIENT.clone(), torch.tensor([0.9, 0.0, 0.0]))
posterior = BodyPosterior(
    distribution=distribution, crop=CropTransform((100.0, 100.0), 200.0, 128),
    keypoints=torch.zeros(17, 2), confidences=torch.ones(17), body=BodyModel())
posterior.vertex_uncertainty(10)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
posterior.vertex_uncertainty({count})
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(base, peak, seconds)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[100, 2000, 20000])
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load "
          f"{os.getloadavg()[0]:.1f}, python {platform.python_version()}")  # fmt: skip
    print()
    print("| n | peak RSS (GB) | added by the call (GB) | seconds | target |")
    print("|---|---|---|---|---|")
    for count in args.counts:
        out = subprocess.run([sys.executable, "-c", CHILD.format(count=count)], check=True,
                             capture_output=True, text=True).stdout.split()  # fmt: skip
        base, peak, seconds = int(out[0]), int(out[1]), float(out[2])
        target = "< 2.5 GB" if count == 20000 else ""
        print(f"| {count} | {peak / 1e6:.2f} | {(peak - base) / 1e6:.2f} | {seconds:.1f} "
              f"| {target} |")  # fmt: skip


if __name__ == "__main__":
    main()

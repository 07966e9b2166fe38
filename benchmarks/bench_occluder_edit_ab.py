"""Occluder edits in the explorer, two versions of ``hkpd`` alternated (issue 58 item 10).

Runs ``benchmarks/bench_explorer.py --real`` (the shipped predictor on the shipped photo, a box
moved over the right shin) once per version per round, the versions alternated round by round
so that both see the same load on a shared machine. Each version is the ``core/`` and
``explorer/`` folders of a git revision (``git archive``), imported as ``hkpd`` and
``hkpd.explorer`` through ``PYTHONPATH`` ahead of the editable install (the assets and the
benchmark itself are the working tree's, the same for both). Prints one row per run (with the
load average before it) and the medians over the rounds.

Usage: python benchmarks/bench_occluder_edit_ab.py [--before f15b4a6~1] [--after HEAD]
       [--rounds 3] [--repeats 10] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = {
    "predict": r"\| occluder: prediction [^|]*\| (\d+) \|",
    "occluder": r"\| \*\*occluder: change -> delivered[^|]*\| (\d+) \|",
    "slider": r"\| \*\*slider: change -> delivered[^|]*\| (\d+) \|",
    "cpu": r"\| occluder: CPU of the edit[^|]*\| (\d+) \|",
}
"""The medians (ms) read from ``bench_explorer.py``'s table."""


def version_tree(revision: str, folder: Path) -> Path:
    """A folder holding ``hkpd`` (revision's ``core/``, its ``explorer/`` inside) for
    ``PYTHONPATH``."""
    tree = folder / revision.replace("/", "_").replace("~", "-")
    tree.mkdir(parents=True)
    command = ["git", "-C", str(ROOT), "archive", revision, "core", "explorer"]
    archive = subprocess.run(command, check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
    (tree / "explorer").rename(tree / "core" / "explorer")
    (tree / "hkpd").symlink_to(tree / "core")
    return tree


def run_once(tree: Path, repeats: int, threads: int) -> dict[str, float]:
    """One ``bench_explorer.py --real`` run with ``tree``'s ``hkpd``: its medians (ms)."""
    environment = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": str(threads)}
    command = [sys.executable, str(ROOT / "benchmarks" / "bench_explorer.py"), "--real"]
    command += ["--repeats", str(repeats), "--threads", str(threads)]
    output = subprocess.run(
        command, env=environment, cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    found = {name: re.search(pattern, output) for name, pattern in ROWS.items()}
    missing = [name for name, match in found.items() if match is None]
    if missing:
        raise RuntimeError(f"bench_explorer.py printed no {missing} row:\n{output}")
    return {name: float(match.group(1)) for name, match in found.items() if match}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default="f15b4a6~1")
    parser.add_argument("--after", default="HEAD")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    results: dict[str, list[dict[str, float]]] = {args.before: [], args.after: []}
    print(f"# occluder edit, {args.before} vs {args.after}, alternated — "
          f"{time.strftime('%Y-%m-%d %H:%M %Z')}")  # fmt: skip
    print(f"{os.cpu_count()} CPUs, torch threads {args.threads}, shared machine\n")
    print("| round | version | load before | occluder: predict ms | occluder: CPU ms | "
          "occluder: change -> delivered ms | slider: change -> delivered ms |")  # fmt: skip
    print("|---:|---|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as folder:
        trees = {rev: version_tree(rev, Path(folder)) for rev in results}
        for round_index in range(args.rounds):
            order = list(results) if round_index % 2 == 0 else list(reversed(results))
            for revision in order:
                load = os.getloadavg()[0]
                medians = run_once(trees[revision], args.repeats, args.threads)
                results[revision].append(medians)
                row = f"| {round_index + 1} | {revision} | {load:.1f} | {medians['predict']:.0f} "
                row += f"| {medians['cpu']:.0f} | {medians['occluder']:.0f} "
                row += f"| {medians['slider']:.0f} |"
                print(row, flush=True)
    print()
    print("| version | occluder: predict ms | occluder: CPU ms | occluder: change -> delivered ms "
          "(target 400) | slider ms (target 100) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|")
    for revision, runs in results.items():
        values = {name: statistics.median(run[name] for run in runs) for name in ROWS}
        print(f"| {revision} | {values['predict']:.0f} | {values['cpu']:.0f} "
              f"| {values['occluder']:.0f} | {values['slider']:.0f} |")  # fmt: skip


if __name__ == "__main__":
    main()

"""Ctrl-C at random moments: ``hkpd-predict`` on a folder, one SIGINT per run at a uniformly
random time, every run checked for exit status 130, one "interrupted" line on stderr, no
traceback and no partial output (no ``.NAME.partial`` folder; every folder left is complete).

The folder holds copies of the shipped CC0 photo; the shipped model. The time range defaults to
one uninterrupted run's wall time (measured first), so the signals land during the imports,
the model load and the photos in proportion to how long each takes.

The ``--late-runs`` runs aim at the end instead: one SIGINT at a uniformly random time between
the moment the progress bar reaches 100 % (every photo done) and the moment an uninterrupted
run calls ``exit`` (its closing report and Python's shutdown; a signal due after it, while the
kernel frees the process, counts as "finished first"). There, before issue 51, Python had
given SIGINT its default action back and the run ended by the signal (status -2, no line).

The programs run as their console scripts do (``hkpd.interrupts.run_program``), each with
SIGINT's default action whatever this script inherited (``nohup ... &`` ignores it).

Usage: python benchmarks/bench_interrupts.py [--runs 20] [--late-runs 20] [--photos 3] [--seed 0]
       [--entry run_program|run_command]
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
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hkpd.explorer.demo_photo import shipped_photo

LAUNCH = (
    "import sys; from hkpd import interrupts; "
    "sys.exit(getattr(interrupts, sys.argv[1])(sys.argv[2], sys.argv[3:]))"
)
"""``python -c LAUNCH ENTRY PROGRAM ARGS...``: ``run_program`` is what the installed
``hkpd-predict`` runs (``hkpd.interrupts:predict``); ``run_command`` (``--entry``) is the
entry point before issue 51, for the comparison."""

ENTRY = ["run_program"]
"""The entry point the runs use (set from ``--entry``)."""

ALL_DONE = b"100%"
"""On stderr when the progress bar is full: every photo is done."""


def default_sigint() -> None:
    """Popen's ``preexec_fn``: SIGINT's default action in the child, as from a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(photos: Path, out: Path) -> subprocess.Popen:
    """hkpd-predict on ``photos`` into ``out``, stderr piped."""
    command = [sys.executable, "-c", LAUNCH, ENTRY[0], "hkpd-predict", str(photos),
               "--out", str(out), "--samples", "1", "--uncertainty-samples", "10"]  # fmt: skip
    return subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=default_sigint
    )


Outcome = tuple[int, str, float, bool]
"""Exit status, stderr, seconds (see each runner) and whether the SIGINT was sent."""


PF_EXITING = 0x4
"""Linux's per-task flag of a process that has called ``exit`` (``/proc/PID/stat`` field 9)."""


def exiting(pid: int) -> bool:
    """Whether process ``pid`` has already called ``exit`` (its status is decided; the kernel
    may still be freeing its memory, tens of ms for hkpd-predict) or is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    fields = stat[stat.rindex(")") + 2 :].split()
    return fields[0] in "ZXx" or bool(int(fields[6]) & PF_EXITING)


def interrupt_after(process: subprocess.Popen, after_s: float | None) -> bool:
    """Send ``process`` one SIGINT after ``after_s`` seconds unless it ended (or called
    ``exit``) before (None: none); whether it was sent."""
    if after_s is None:
        return False
    try:
        process.wait(timeout=after_s)
    except subprocess.TimeoutExpired:
        if exiting(process.pid):
            return False
        process.send_signal(signal.SIGINT)
        return True
    return False


def run(photos: Path, out: Path, after_s: float | None) -> Outcome:
    """hkpd-predict on ``photos``, SIGINT after ``after_s`` (None: none); the seconds are the
    run's."""
    began = time.perf_counter()
    process = start(photos, out)
    sent = interrupt_after(process, after_s)
    _, err = process.communicate(timeout=300)
    return process.returncode, err.decode(errors="replace"), time.perf_counter() - began, sent


def run_to_the_end(photos: Path, out: Path, after_s: float | None) -> Outcome:
    """hkpd-predict on ``photos``, SIGINT ``after_s`` after the progress bar is full; the
    seconds are from the full bar to the process's end. With ``after_s`` None no SIGINT, and
    the seconds are from the full bar to the moment the process calls ``exit`` (polled every
    millisecond): the window in which a Ctrl-C still reaches the program."""
    process = start(photos, out)
    seen = b""
    while ALL_DONE not in seen and process.poll() is None:
        seen += os.read(process.stderr.fileno(), 4096)
    full = time.perf_counter()
    sent = interrupt_after(process, after_s)
    if after_s is None:
        while not exiting(process.pid):
            time.sleep(0.001)
    until_exit = time.perf_counter() - full
    _, err = process.communicate(timeout=300)
    stderr = (seen + err).decode(errors="replace")
    seconds = until_exit if after_s is None else time.perf_counter() - full
    return process.returncode, stderr, seconds, sent


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
    parser.add_argument("--late-runs", type=int, default=20)
    parser.add_argument("--photos", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--entry", choices=("run_program", "run_command"), default="run_program")
    args = parser.parse_args()
    ENTRY[0] = args.entry
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as temp:
        photos = Path(temp) / "photos"
        photos.mkdir()
        for index in range(args.photos):
            shutil.copy(shipped_photo(), photos / f"photo_{index}.jpg")
        status, stderr, full_s, _ = run(photos, Path(temp) / "full", None)
        assert status == 0, stderr
        status, stderr, end_s, _ = run_to_the_end(photos, Path(temp) / "full_end", None)
        assert status == 0, stderr
        print(f"# hkpd-predict Ctrl-C benchmark — {time.strftime('%Y-%m-%d %H:%M %Z')}")
        load = os.getloadavg()[0]
        print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, load average {load:.1f}; "
              f"{args.photos} photos, uninterrupted {full_s:.1f} s, of which {end_s:.3f} s "
              f"from the full progress bar to its exit call; entry point {args.entry}")  # fmt: skip
        failures = table(
            "whole run", args.runs, lambda: float(rng.uniform(0.2, full_s)), photos, temp, run
        )
        failures += table(
            "after the last photo", args.late_runs, lambda: float(rng.uniform(0.0, end_s)),
            photos, temp, run_to_the_end,
        )  # fmt: skip
        print()
        total = args.runs + args.late_runs
        print(f"{total - failures} of {total} runs as they should be")


def table(
    title: str,
    runs: int,
    draw: Callable[[], float],
    photos: Path,
    temp: str,
    runner: Callable[[Path, Path, float | None], Outcome],
) -> int:
    """``runs`` runs of ``runner`` with a SIGINT at ``draw()`` seconds, one table row each;
    returns how many went wrong."""
    print()
    print(f"## SIGINT at a random moment: {title}")
    print()
    print("| run | SIGINT at s | exit | stopped after s | folders left | problems |")
    print("|---:|---:|---:|---:|---:|---|")
    failures = 0
    stderr_of_failures: list[str] = []
    for index in range(runs):
        out = Path(temp) / f"out_{title.split()[0]}_{index}"
        after_s = draw()
        status, stderr, seconds, sent = runner(photos, out, after_s)
        finished = not sent  # it ended (or called exit) before the signal was due
        found = problems(status, stderr, out, interrupted=not finished)
        failures += bool(found)
        if found:
            stderr_of_failures.append(f"run {index}: ...{stderr[-800:]}")
        left = len(list(out.iterdir())) if out.exists() else 0
        print(f"| {index} | {after_s:.3f} | {status} | {seconds:.3f} | {left} | "
              f"{', '.join(found) or ('none (finished first)' if finished else 'none')} |",
              flush=True)  # fmt: skip
    for text in stderr_of_failures:  # what went wrong, below the table
        print(f"\n```\n{text.strip()}\n```")
    return failures


if __name__ == "__main__":
    main()

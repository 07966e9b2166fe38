"""Timing helpers shared by the benchmark scripts (imported as ``timing`` when a script in this
folder runs: Python puts the script's folder on the import path).

This VM shares its host, so timings drift between runs: tables report the median (what a user
typically sees), the best call (what the code achieves undisturbed) and, where useful, the
process CPU time (all threads), which is robust to other processes competing for the cores.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def call_times(
    action: Callable[[], object],
    repeats: int,
    warmups: int = 1,
    synchronise: Callable[[], object] | None = None,
) -> tuple[list[float], list[float]]:
    """Wall and process-CPU seconds of ``repeats`` calls, after ``warmups`` untimed calls.

    Args:
        synchronise: called before starting and before stopping each clock (e.g.
            ``torch.cuda.synchronize``), so asynchronous device work is counted.
    """
    for _ in range(warmups):
        action()
    walls, cpus = [], []
    for _ in range(repeats):
        if synchronise is not None:
            synchronise()
        start, start_cpu = time.perf_counter(), time.process_time()
        action()
        if synchronise is not None:
            synchronise()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - start_cpu)
    return walls, cpus


def median_and_best(
    action: Callable[[], object], repeats: int, warmups: int = 1
) -> tuple[float, float]:
    """(median, best) wall seconds of ``action``."""
    walls, _ = call_times(action, repeats, warmups)
    return statistics.median(walls), min(walls)


def median_best_and_cpu(
    action: Callable[[], object], repeats: int, warmups: int = 1
) -> tuple[float, float, float]:
    """(median wall, best wall, median process CPU) seconds of ``action``."""
    walls, cpus = call_times(action, repeats, warmups)
    return statistics.median(walls), min(walls), statistics.median(cpus)

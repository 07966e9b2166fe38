"""Synthetic batches made by several worker processes, in the same order as one process would.

Torch's intra-op thread pool gains little on the generator's many small operations, so on a
multi-core CPU it is faster to run one single-threaded generator per core. Worker ``w`` of
``W`` makes batches ``start + w, start + w + W, ...``; the consumer reads the workers' queues
round-robin, so the stream is exactly :class:`~hkpd.synthesis.generator.SyntheticBatches`'
(batch ``i`` depends only on ``(seed, i)``), whatever the number of workers.

Workers send :class:`~hkpd.synthesis.batch.PackedBatch` (uint8 edges and keypoints, ~1/18 of
the float proxy's bytes) and the consumer draws the heatmaps, so little memory crosses the
process boundary.
"""

from __future__ import annotations

import queue
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import torch
import torch.multiprocessing as multiprocessing

from hkpd.cpu_allocator import keep_freed_memory
from hkpd.poses import pose_source
from hkpd.poses.mixed_source import PoseMix
from hkpd.synthesis.batch import PackedBatch, TrainingBatch
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator, batch_seed


@dataclass(frozen=True)
class GeneratorSpec:
    """Everything a worker needs to build its own generator (picklable).

    Attributes:
        poses: pose bank file, or None for the procedural prior.
        split: the pose bank split.
        config: the synthetic data settings.
        backgrounds: optional background image folder.
        pose_mix: pose families and limb mixes next to the bank's poses (None: the bank).
    """

    poses: Path | None = None
    split: str = "train"
    config: SyntheticDataConfig = field(default_factory=SyntheticDataConfig)
    backgrounds: Path | None = None
    pose_mix: PoseMix | None = None

    def build(self, device: str = "cpu") -> SyntheticDataGenerator:
        source = pose_source(self.poses, self.split, self.pose_mix)
        return SyntheticDataGenerator(source, self.config, device, self.backgrounds)


def _work(
    spec: GeneratorSpec,
    batch_size: int,
    seed: int,
    first: int,
    step: int,
    out,
    keep_memory: bool,
) -> None:
    torch.set_num_threads(1)
    if keep_memory:
        keep_freed_memory()
    generator = spec.build()
    index = first
    while True:
        out.put(generator.generate_packed(batch_size, batch_seed(seed, index)))
        index += step


class ParallelBatches(Iterator[TrainingBatch]):
    """An endless stream of CPU training batches from ``workers`` processes.

    Args:
        spec: how each worker builds its generator.
        batch_size, seed, start: as for :class:`~hkpd.synthesis.generator.SyntheticBatches`.
        workers: processes (each single-threaded).
        depth: batches each worker may make ahead.
        keep_memory: workers keep freed memory for reuse (:mod:`hkpd.cpu_allocator`), which
            saves their page faults; False leaves the allocator alone.

    Use :meth:`close` (or a ``with`` block) to stop the workers.
    """

    def __init__(
        self,
        spec: GeneratorSpec,
        batch_size: int,
        seed: int = 0,
        start: int = 0,
        workers: int = 2,
        depth: int = 2,
        keep_memory: bool = True,
    ) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        context = multiprocessing.get_context("spawn")
        self._queues = [context.Queue(maxsize=depth) for _ in range(workers)]
        self._processes = [
            context.Process(
                target=_work,
                args=(spec, batch_size, seed, start + w, workers, self._queues[w], keep_memory),
                daemon=True,
            )
            for w in range(workers)
        ]
        for process in self._processes:
            process.start()
        self._next = 0

    def __next__(self) -> TrainingBatch:
        source = self._queues[self._next % len(self._queues)]
        process = self._processes[self._next % len(self._processes)]
        while True:
            try:
                packed: PackedBatch = source.get(timeout=1.0)
                break
            except queue.Empty:
                if not process.is_alive():
                    raise RuntimeError(
                        f"a data worker stopped (exit code {process.exitcode}); run with "
                        "workers=0 to see its error in this process"
                    ) from None
        self._next += 1
        return packed.unpack()

    def close(self) -> None:
        for process in self._processes:
            process.terminate()
        for process in self._processes:
            process.join(timeout=5)

    def __enter__(self) -> ParallelBatches:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

"""Data-parallel training under ``torchrun``: which process this is, and what the processes share.

``torchrun --nproc-per-node N hkpd-train ...`` starts N copies of ``hkpd-train`` with
``WORLD_SIZE``, ``RANK`` and ``LOCAL_RANK`` in their environment. Each copy (a *rank*) trains
the same network, wrapped in :class:`~torch.nn.parallel.DistributedDataParallel`, on its own
synthetic stream, so one optimiser step sees ``batch_size x world_size`` examples:

- the backend is gloo on CPU and NCCL on CUDA, one GPU per local rank (``cuda:LOCAL_RANK``);
- rank ``r`` draws the data stream of seed ``seed + r`` (:func:`rank_seed`), so rank 0 sees
  what a single-process run with the same seed sees, and a run is reproducible from its seed
  and world size;
- DistributedDataParallel averages the gradients over the ranks; the loss terms a rank logs
  are averaged the same way (:func:`average_and_any`), together with the reasons to stop, so
  every rank stops at the same step;
- every rank's random states go into the checkpoint (:func:`gather_to_main`).

A process started without ``torchrun`` is rank 0 of a world of 1, and none of this applies:
no process group, no wrapper, no collective. :class:`Launch` and :func:`detect_launch` live in
:mod:`hkpd.launch` (``hkpd-predict`` reads them too).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel

from hkpd.launch import LAUNCH_VARIABLES, Launch, detect_launch

__all__ = [
    "LAUNCH_VARIABLES", "Launch", "average_and_any", "detect_launch", "end_process_group",
    "gather_to_main", "launch_device", "rank_seed", "start_process_group", "wrap_for_training",
]  # fmt: skip


def launch_device(device: torch.device, launch: Launch) -> torch.device:
    """The device this rank trains on: ``cuda:LOCAL_RANK`` for CUDA, the CPU as it is.

    Raises:
        ValueError: a multi-process launch on a device without a backend here (MPS), or with
            more local ranks than GPUs.
    """
    if not launch.distributed:
        return device
    if device.type == "cuda":
        if launch.local_rank >= torch.cuda.device_count():
            raise ValueError(
                f"local rank {launch.local_rank} has no GPU of its own: torch sees "
                f"{torch.cuda.device_count()}; use --nproc-per-node <= the number of GPUs"
            )
        return torch.device("cuda", launch.local_rank)
    if device.type != "cpu":
        raise ValueError(f"multi-process training runs on cpu or cuda, not {device.type}")
    return device


def rank_seed(seed: int, rank: int) -> int:
    """The seed of rank ``rank``'s data stream (rank 0 keeps the run's seed)."""
    return seed + rank


def start_process_group(launch: Launch, device: torch.device) -> None:
    """Join the other ranks (gloo on CPU, NCCL on CUDA); nothing for a single process."""
    if not launch.distributed or dist.is_initialized():
        return
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(
        "nccl" if device.type == "cuda" else "gloo", rank=launch.rank,
        world_size=launch.world_size,
    )  # fmt: skip


GLOO_RELEASE_S = 0.2
"""How long :func:`end_process_group` lets gloo's worker threads release a finished run's last
collectives before the group can be torn down, seconds."""


def end_process_group(wait_for_all: bool = False) -> None:
    """Leave the process group, if this process joined one.

    Args:
        wait_for_all: first wait until every rank has come here (a finished run). Gloo's
            worker threads release a collective's tensors after it returns, which needs the
            GIL. Tearing the group down (``~ProcessGroupGloo`` joins those threads, holding the
            GIL: when the DDP wrapper is freed at the end of ``main``) before they have done so
            hangs the process at exit. The barrier waits for every rank's last collective; the
            barrier's own work, which keeps the collectives before it (``gather_object``'s
            tensors), is released by a worker thread just after the barrier returns, so this
            process then sleeps :data:`GLOO_RELEASE_S` (the GIL free) to let it. Without the
            sleep, 2 of 48 two-process runs hung at exit on a loaded 2-core machine. A run
            that failed leaves without either (the other ranks may be gone).
    """
    if not dist.is_initialized():
        return
    if wait_for_all:
        dist.barrier()
        time.sleep(GLOO_RELEASE_S)
    dist.destroy_process_group()


def wrap_for_training(
    network: torch.nn.Module, launch: Launch, device: torch.device
) -> torch.nn.Module:
    """The module a training step calls: ``network`` itself alone, else its DDP wrapper.

    The wrapper starts every rank from rank 0's weights and averages the gradients in
    ``backward``. Batch normalisation stays per rank: each rank normalises with its own
    batch's statistics, and rank 0's running statistics are the ones kept.
    """
    if not launch.distributed:
        return network
    device_ids = [device.index] if device.type == "cuda" else None
    return DistributedDataParallel(network, device_ids=device_ids)


def average_and_any(
    terms: dict[str, torch.Tensor], flags: Sequence[bool], launch: Launch
) -> tuple[dict[str, torch.Tensor], tuple[bool, ...]]:
    """Loss terms averaged over the ranks, and each flag true where it is true on any rank.

    One collective (a sum of a small vector on the terms' device), so every rank leaves with
    the same numbers. Alone, ``terms`` come back as they are (the same tensors).

    Args:
        terms: scalar tensors, with the same names in the same order on every rank.
        flags: booleans (e.g. "stop requested", "out of time"), the same count on every rank.
    """
    if not launch.distributed:
        return terms, tuple(bool(flag) for flag in flags)
    names = list(terms)
    device = terms[names[0]].device
    values = [terms[name].detach().float().reshape(()) for name in names]
    values += [torch.tensor(float(flag), device=device) for flag in flags]
    summed = torch.stack(values)
    dist.all_reduce(summed)
    averaged = {name: summed[index] / launch.world_size for index, name in enumerate(names)}
    return averaged, tuple(bool(value > 0) for value in summed[len(names) :].tolist())


def gather_to_main(value: object, launch: Launch) -> list[object] | None:
    """Every rank's ``value`` (pickled), as a list by rank on rank 0; None on the others.

    Alone, ``[value]``. Every rank must call it at the same point.
    """
    if not launch.distributed:
        return [value]
    gathered: list[object] | None = [None] * launch.world_size if launch.is_main else None
    dist.gather_object(value, gathered, dst=0)
    return gathered

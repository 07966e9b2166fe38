"""Average the weights of several checkpoints of one run (tail averaging, as in SWA).

Late in a run, with a small learning rate, successive checkpoints scatter around a minimum;
their mean often sits closer to it than any one of them. Batch-norm running statistics are
averaged like the weights (a fair approximation when the checkpoints are close, i.e. from the
low-rate tail of one run); integer buffers (batch counters) are taken from the last file.

Usage: ``python -m hkpd.training.average_weights a.pt b.pt c.pt --out averaged.pt``, with copies
of a run's ``last.pt`` taken at several steps (``hkpd-train`` keeps only the latest).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from hkpd.network.checkpoint import (
    CheckpointError,
    load_network,
    save_checkpoint,
    stored_evidence_config,
)


def average_state_dicts(states: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """The element-wise mean of float tensors; other tensors from the last state.

    Args:
        states: state dicts with the same keys and shapes (at least one).

    Returns:
        A state dict of float32 means (accumulated in float64).

    Raises:
        ValueError: no states, or states whose keys or shapes differ.
    """
    if not states:
        raise ValueError("nothing to average: give at least one checkpoint")
    keys = set(states[0])
    for index, state in enumerate(states[1:], start=1):
        if set(state) != keys:
            differing = sorted(keys.symmetric_difference(state))[:5]
            raise ValueError(f"state {index} has other tensors than state 0 ({differing})")
    averaged = {}
    for key, last in states[-1].items():
        shapes = {tuple(state[key].shape) for state in states}
        if len(shapes) > 1:
            raise ValueError(f"tensor {key} has different shapes: {sorted(shapes)}")
        if last.is_floating_point():
            total = sum(state[key].double() for state in states)
            averaged[key] = (total / len(states)).float()
        else:
            averaged[key] = last.clone()
    return averaged


def average_checkpoints(paths: list[Path], out: Path, half_precision: bool = False) -> Path:
    """Write the mean of ``paths``' networks to ``out`` (weights only: no optimiser state).

    The result keeps the last file's step, sample count and training config.

    Raises:
        FileNotFoundError: a file is missing.
        CheckpointError: a file is not a readable checkpoint.
        ValueError: the checkpoints hold different architectures, or ``out`` is one of them.
    """
    paths = [Path(path) for path in paths]
    if Path(out).resolve() in {path.resolve() for path in paths}:
        raise ValueError(f"--out {out} is one of the inputs; write the average to a new file")
    networks, payloads = zip(*(load_network(path) for path in paths), strict=True)
    architecture = payloads[0]["network_config"]
    for path, payload in zip(paths, payloads, strict=True):
        if payload["network_config"] != architecture:
            raise ValueError(
                f"{path} holds architecture {payload['network_config']}, but {paths[0]} holds "
                f"{architecture}: only checkpoints of one run can be averaged"
            )
    network = networks[-1]
    network.load_state_dict(average_state_dicts([n.state_dict() for n in networks]))
    last = payloads[-1]
    return save_checkpoint(
        out, network, architecture, last["step"], last["train_config"], last["samples_seen"],
        half_precision=half_precision, evidence_config=stored_evidence_config(last) or None,
    )  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoints", type=Path, nargs="+", help="checkpoints of one run")
    parser.add_argument("--out", type=Path, required=True, help="file for the averaged weights")
    parser.add_argument("--half", action="store_true", help="store float16 (shipping size)")
    arguments = parser.parse_args(argv)
    if arguments.out.exists():
        parser.error(f"{arguments.out} exists; choose another name (nothing was written)")
    try:
        path = average_checkpoints(arguments.checkpoints, arguments.out, arguments.half)
    except (FileNotFoundError, CheckpointError, ValueError) as error:
        print(f"average_weights: error: {error}", file=sys.stderr)
        return 2
    steps = len(arguments.checkpoints)
    print(f"wrote {path}: the mean of {steps} checkpoints ({path.stat().st_size / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The command line shared by the synthetic-test-set experiment scripts in ``docs/experiments/``.

Each script reads one checkpoint on the fixed synthetic test set of a pose bank:
``python docs/experiments/<script>.py CHECKPOINT [--poses poses.npz] [--count 1000]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def parse_experiment_arguments(description: str, argv: list[str] | None) -> argparse.Namespace:
    """``checkpoint`` (Path), ``poses`` (Path or None: procedural poses) and ``count`` (examples
    per split, default 1000) from ``argv`` (None: the process's arguments)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--poses", type=Path, help="pose bank (its test split); else procedural")
    parser.add_argument("--count", type=int, default=1000)
    return parser.parse_args(argv)

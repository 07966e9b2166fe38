"""Which process of a ``torchrun`` launch this is, read from the variables torchrun sets.

``torchrun --nproc-per-node N PROGRAM ...`` starts N copies of ``PROGRAM`` with ``WORLD_SIZE``,
``RANK``, ``LOCAL_RANK`` and ``LOCAL_WORLD_SIZE`` in their environment (several machines:
``WORLD_SIZE`` counts the processes of all of them). ``hkpd-train`` trains one network over
the processes (:mod:`hkpd.training.distributed`); ``hkpd-predict`` splits the photos among
them (:mod:`hkpd.prediction.dataset_run`). A process started without torchrun is rank 0 of a
world of 1. Torch-free.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

LAUNCH_VARIABLES = ("WORLD_SIZE", "RANK", "LOCAL_RANK")


@dataclass(frozen=True)
class Launch:
    """Where this process sits in a launch: rank ``rank`` of ``world_size`` (0 of 1 alone).

    Attributes:
        rank: this process's index among all processes (0 logs, validates and saves).
        local_rank: its index on this machine (which GPU it uses).
        world_size: processes working together.
    """

    rank: int = 0
    local_rank: int = 0
    world_size: int = 1

    @property
    def is_main(self) -> bool:
        """The process that logs, validates, draws the curves and writes checkpoints."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.world_size > 1


def detect_launch(environment: Mapping[str, str] | None = None) -> Launch:
    """The launch described by torchrun's ``WORLD_SIZE``/``RANK``/``LOCAL_RANK`` variables.

    Args:
        environment: the variables to read (default: ``os.environ``).

    Raises:
        ValueError: some of the variables are set but not all, or their values do not fit.
    """
    environment = os.environ if environment is None else environment
    given = {name: environment.get(name) for name in LAUNCH_VARIABLES}
    if all(value is None for value in given.values()):
        return Launch()
    missing = [name for name, value in given.items() if value is None]
    if missing:
        raise ValueError(
            f"the environment names a torchrun launch but lacks {', '.join(missing)}; start "
            "the program with torchrun, or without any of WORLD_SIZE, RANK and LOCAL_RANK"
        )
    try:
        launch = Launch(
            rank=int(given["RANK"]), local_rank=int(given["LOCAL_RANK"]),
            world_size=int(given["WORLD_SIZE"]),
        )  # fmt: skip
    except ValueError as error:
        raise ValueError(f"torchrun's launch variables are not integers: {given}") from error
    if not (launch.world_size >= 1 and 0 <= launch.rank < launch.world_size):
        raise ValueError(f"torchrun's launch variables do not fit together: {given}")
    if launch.local_rank < 0:
        raise ValueError(f"LOCAL_RANK must be >= 0, got {launch.local_rank}")
    return launch


def local_world_size(environment: Mapping[str, str] | None = None) -> int:
    """How many processes of the launch run on this machine (torchrun's ``LOCAL_WORLD_SIZE``;
    1 without torchrun or when it is not set or not a positive integer)."""
    environment = os.environ if environment is None else environment
    try:
        return max(1, int(environment.get("LOCAL_WORLD_SIZE", "1")))
    except ValueError:
        return 1

"""``hkpd-train``: train the distribution-prediction network on synthetic data.

Examples::

    hkpd-train --out runs/demo --steps 200 --image-size 128 --backbone-base-width 16
    hkpd-train --poses poses.npz --backgrounds ~/lsun --out runs/full
    hkpd-train --out runs/full --resume          # continue where it stopped
    hkpd-train --out runs/full --resume --max-minutes 8   # train for 8 minutes, then checkpoint
    torchrun --standalone --nproc-per-node 4 -m hkpd.training.cli --out runs/4gpu ...
        # four processes (one GPU each), DistributedDataParallel; --batch-size per process

Under torchrun, rank 0 alone prints; the other ranks report only errors of their own.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from hkpd.interrupts import INTERRUPTED_STATUS, interrupted
from hkpd.training.config import TrainConfig, add_config_arguments, config_from_arguments

if TYPE_CHECKING:
    from hkpd.training.distributed import Launch


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hkpd-train",
        description="Train hkpd's distribution-prediction network on synthetic data rendered on "
        "the fly. Every TrainConfig field is a flag; --config loads a saved config.json first.",
    )
    parser.add_argument("--config", type=Path, help="a config.json to start from")
    parser.add_argument(
        "--resume", action="store_true", help="continue from OUT/last.pt (and its config)"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    add_config_arguments(parser)
    return parser


def _report(error: Exception, launch: Launch, during_setup: bool) -> None:
    """Print ``error`` once per run under torchrun, with the rank when it is not rank 0.

    A setup error is the same on every rank of a machine, so rank 0 and the first rank of each
    other machine print it; a non-finite loss stops every rank together and rank 0 prints it;
    any other error is printed by the rank it happened on.
    """
    shared = during_setup or isinstance(error, FloatingPointError)
    if launch.is_main:
        print(f"hkpd-train: error: {error}", file=sys.stderr)
    elif not shared or (during_setup and launch.local_rank == 0):
        print(f"hkpd-train: rank {launch.rank}: error: {error}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    arguments = build_parser().parse_args(argv)
    from hkpd.training.distributed import Launch, detect_launch

    launch, during_setup = Launch(), True
    try:
        launch = detect_launch()
        if arguments.resume and arguments.config is None:
            out = arguments.out or TrainConfig().out
            if (Path(out) / "config.json").is_file():
                arguments.config = Path(out) / "config.json"
        config = config_from_arguments(arguments)
        from hkpd.cpu_allocator import keep_freed_memory
        from hkpd.training.distributed import end_process_group
        from hkpd.training.loop import TrainingRun, build_training

        keep_freed_memory()  # a long CPU job: reuse big blocks instead of re-faulting them

        setup = build_training(config, resume=arguments.resume, launch=launch)
        during_setup, result = False, None
        try:
            result = TrainingRun(setup, show_progress=not arguments.quiet).run()
        finally:
            end_process_group(wait_for_all=result is not None)
    except (OSError, ValueError, FloatingPointError) as error:
        _report(error, launch, during_setup)
        return 2
    except KeyboardInterrupt:  # during setup, or a second Ctrl-C: no checkpoint of this step
        if not launch.is_main:
            return INTERRUPTED_STATUS
        return interrupted("hkpd-train", "; --resume continues from the last checkpoint")
    if not launch.is_main:
        return 130 if result.interrupted else 0
    state = "interrupted" if result.interrupted else "finished"
    if result.out_of_time:
        state = f"stopped at --max-minutes {config.max_minutes:g}"
    print(
        f"{state}: {result.steps} steps, {result.samples_seen} samples in "
        f"{result.seconds / 60:.1f} min; checkpoint {result.checkpoint}; curves "
        f"{result.checkpoint.parent / 'curves.png'}"
    )
    return 130 if result.interrupted else 0


if __name__ == "__main__":
    raise SystemExit(main())

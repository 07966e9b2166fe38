"""``hkpd-train``: train the distribution-prediction network on synthetic data.

Examples::

    hkpd-train --out runs/demo --steps 200 --image-size 128 --backbone-base-width 16
    hkpd-train --poses poses.npz --backgrounds ~/lsun --out runs/full
    hkpd-train --out runs/full --resume          # continue where it stopped
    hkpd-train --out runs/full --resume --max-minutes 8   # train for 8 minutes, then checkpoint
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hkpd.training.config import TrainConfig, add_config_arguments, config_from_arguments


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


def main(argv: list[str] | None = None) -> int:
    arguments = build_parser().parse_args(argv)
    try:
        if arguments.resume and arguments.config is None:
            out = arguments.out or TrainConfig().out
            if (Path(out) / "config.json").is_file():
                arguments.config = Path(out) / "config.json"
        config = config_from_arguments(arguments)
        from hkpd.cpu_allocator import keep_freed_memory
        from hkpd.training.loop import train

        keep_freed_memory()  # a long CPU job: reuse big blocks instead of re-faulting them

        result = train(config, resume=arguments.resume, show_progress=not arguments.quiet)
    except (OSError, ValueError, FloatingPointError) as error:
        print(f"hkpd-train: error: {error}", file=sys.stderr)
        return 2
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

"""The paper's ablation: the four combinations of pose head and 2D samples loss, trained alike.

``python -m hkpd.training.ablation --out runs/ablation --poses poses.npz --steps 4500 ...``
trains, one after the other and with identical settings otherwise (data stream, seed, steps,
loss schedule), the four configurations of the paper's ablation:

===========================  ===============  ==================
run                          pose head        2D samples loss
===========================  ===============  ==================
``independent_no_samples``   independent      off
``independent_samples``      independent      from ``--samples-loss-from``
``hierarchical_no_samples``  hierarchical     off
``hierarchical_samples``     hierarchical     from ``--samples-loss-from``
===========================  ===============  ==================

Each run lives in ``OUT/<run>/`` (resumable: a finished run is skipped, an interrupted one
continues from its ``last.pt``) and is exported as float16 weights to ``OUT/<run>.pt``. Every
other ``hkpd-train`` flag sets the shared base configuration. The command finally prints the
``hkpd-eval`` line that compares the four (synthetic test set: MPJPE-SC, MPJPE-PA, PVE-T-SC, and
the 2D joint error of the mode and of the samples).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from hkpd.training.config import TrainConfig, add_config_arguments, config_from_arguments

ABLATION_RUNS: dict[str, dict[str, object]] = {
    "independent_no_samples": {"pose_head": "independent", "samples_loss": False},
    "independent_samples": {"pose_head": "independent", "samples_loss": True},
    "hierarchical_no_samples": {"pose_head": "hierarchical", "samples_loss": False},
    "hierarchical_samples": {"pose_head": "hierarchical", "samples_loss": True},
}
"""The four configurations, in the paper's table order."""

CHECKPOINT_NAME = "last.pt"


def ablation_configs(base: TrainConfig, out: Path) -> dict[str, TrainConfig]:
    """The four run configurations derived from ``base`` (its ``out`` is replaced).

    Args:
        base: the shared settings; its ``samples_loss_from`` is used by the runs with the
            samples loss and replaced by -1 (never) for the others.
        out: the ablation folder; run ``name`` trains in ``out / name``.

    Raises:
        ValueError: ``base`` never switches the samples loss on, so two runs would be equal.
    """
    if base.samples_loss_from < 0:
        raise ValueError(
            "the ablation compares runs with and without the 2D samples loss: give "
            "--samples-loss-from a step >= 0"
        )
    configs = {}
    for name, settings in ABLATION_RUNS.items():
        configs[name] = dataclasses.replace(
            base,
            out=out / name,
            pose_head=str(settings["pose_head"]),
            samples_loss_from=base.samples_loss_from if settings["samples_loss"] else -1,
        )
    return configs


def run_ablation(base: TrainConfig, out: Path, show_progress: bool = True) -> dict[str, Path]:
    """Train (or finish) the four runs and export each; returns ``{run: exported weights}``."""
    from hkpd.training.checkpoint import read_checkpoint
    from hkpd.training.export import export_weights
    from hkpd.training.loop import train

    exported = {}
    for name, config in ablation_configs(base, out).items():
        checkpoint = Path(config.out) / CHECKPOINT_NAME
        weights = out / f"{name}.pt"
        finished = checkpoint.is_file() and int(read_checkpoint(checkpoint)["step"]) >= config.steps
        if not finished:
            print(f"ablation: training {name} ({config.steps} steps) in {config.out}", flush=True)
            result = train(config, resume=checkpoint.is_file(), show_progress=show_progress)
            if result.interrupted:
                raise KeyboardInterrupt(f"ablation interrupted during {name}; run again to resume")
        if not weights.is_file() or weights.stat().st_mtime < checkpoint.stat().st_mtime:
            export_weights(checkpoint, weights)
        exported[name] = weights
    return exported


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hkpd.training.ablation",
        description="Train the paper's four ablation configurations (independent/hierarchical "
        "pose head, with/without the 2D samples loss) with otherwise identical settings.",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    add_config_arguments(parser)
    arguments = parser.parse_args(argv)
    if arguments.out is None:
        parser.error("--out (the ablation folder) is required")
    base = config_from_arguments(arguments)
    try:
        from hkpd.cpu_allocator import keep_freed_memory

        keep_freed_memory()
        exported = run_ablation(base, Path(arguments.out), show_progress=not arguments.quiet)
    except (FileNotFoundError, ValueError) as error:
        print(f"ablation: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:
        print(f"ablation: {stop}", file=sys.stderr)
        return 130
    poses = f" --poses {base.poses}" if base.poses else ""
    checkpoints = " ".join(str(path) for path in exported.values())
    print("ablation finished; compare the four with:")
    print(f"  hkpd-eval {checkpoints}{poses}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

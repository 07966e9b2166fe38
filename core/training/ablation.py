"""The paper's ablations (Table 1), each set of models trained alike.

``python -m hkpd.training.ablation --out runs/ablation --poses poses.npz --steps 4500 ...``
trains, one after the other and with identical settings otherwise (data stream, seed, steps,
loss schedule), the four configurations of the paper's head and loss ablation (rows 3-6):

===========================  ===============  ==================
run                          pose head        2D samples loss
===========================  ===============  ==================
``independent_no_samples``   independent      off
``independent_samples``      independent      from ``--samples-loss-from``
``hierarchical_no_samples``  hierarchical     off
``hierarchical_samples``     hierarchical     from ``--samples-loss-from``
===========================  ===============  ==================

With ``--study proxies`` it trains the three input proxies of rows 1-3 instead: a
silhouette, the synthetic RGB image, or the edge image, each with the 17 joint heatmaps, all
with the independent head and without the samples loss, as in the paper:

===========================  ===============  ==================
run                          image proxy      pose head, loss
===========================  ===============  ==================
``proxy_silhouette``         silhouette       independent, off
``proxy_rgb``                RGB              independent, off
``proxy_edges``              edges            independent, off
===========================  ===============  ==================

Each run lives in ``OUT/<run>/`` (resumable: a finished run is skipped, an interrupted one
continues from its ``last.pt``) and is exported as float16 weights to ``OUT/<run>.pt``. Every
other ``hkpd-train`` flag sets the shared base configuration. The command finally prints the
``hkpd-eval`` line that compares them (synthetic test set: MPJPE-SC, MPJPE-PA, PVE-T-SC, and
the 2D joint error of the mode and of the samples; add ``--coco`` for real photos).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from hkpd.cpu_allocator import keep_freed_memory
from hkpd.network.checkpoint import read_checkpoint
from hkpd.training.config import TrainConfig, add_config_arguments, config_from_arguments

ABLATION_RUNS: dict[str, dict[str, object]] = {
    "independent_no_samples": {"pose_head": "independent", "samples_loss": False},
    "independent_samples": {"pose_head": "independent", "samples_loss": True},
    "hierarchical_no_samples": {"pose_head": "hierarchical", "samples_loss": False},
    "hierarchical_samples": {"pose_head": "hierarchical", "samples_loss": True},
}
"""The four configurations of the head and loss study, in the paper's table order."""

PROXY_RUNS: dict[str, dict[str, object]] = {
    "proxy_silhouette": {"image_proxy": "silhouette", "pose_head": "independent",
                         "samples_loss": False},
    "proxy_rgb": {"image_proxy": "rgb", "pose_head": "independent", "samples_loss": False},
    "proxy_edges": {"image_proxy": "edges", "pose_head": "independent", "samples_loss": False},
}  # fmt: skip
"""The three input proxies of the proxy study (paper's Table 1, rows 1-3), in its order."""

STUDIES: dict[str, dict[str, dict[str, object]]] = {"heads": ABLATION_RUNS, "proxies": PROXY_RUNS}
"""``--study`` choices: the head and loss study, or the input proxy study."""

CHECKPOINT_NAME = "last.pt"


def ablation_configs(base: TrainConfig, out: Path, study: str = "heads") -> dict[str, TrainConfig]:
    """The run configurations of ``study`` derived from ``base`` (its ``out`` is replaced).

    Args:
        base: the shared settings; its ``samples_loss_from`` is used by the runs with the
            samples loss and replaced by -1 (never) for the others.
        out: the ablation folder; run ``name`` trains in ``out / name``.
        study: ``"heads"`` (four runs) or ``"proxies"`` (three runs; see :data:`STUDIES`).

    Raises:
        ValueError: an unknown study, or a heads study whose ``base`` never switches the
            samples loss on (so two runs would be equal).
    """
    if study not in STUDIES:
        raise ValueError(f"unknown study {study!r}; choose one of {', '.join(STUDIES)}")
    if study == "heads" and base.samples_loss_from < 0:
        raise ValueError(
            "the ablation compares runs with and without the 2D samples loss: give "
            "--samples-loss-from a step >= 0"
        )
    configs = {}
    for name, settings in STUDIES[study].items():
        configs[name] = dataclasses.replace(
            base,
            out=out / name,
            pose_head=str(settings["pose_head"]),
            samples_loss_from=base.samples_loss_from if settings["samples_loss"] else -1,
            image_proxy=str(settings.get("image_proxy", base.image_proxy)),
        )
    return configs


def run_ablation(
    base: TrainConfig, out: Path, show_progress: bool = True, study: str = "heads"
) -> dict[str, Path]:
    """Train (or finish) the runs of ``study`` and export each; returns
    ``{run: exported weights}``."""
    from hkpd.training.export import export_weights
    from hkpd.training.loop import train

    exported = {}
    for name, config in ablation_configs(base, out, study).items():
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
        description="Train the paper's ablation configurations with otherwise identical "
        "settings: the four of independent/hierarchical pose head with/without the 2D samples "
        "loss (--study heads), or the three input proxies silhouette/RGB/edges + heatmaps "
        "(--study proxies).",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument(
        "--study", choices=sorted(STUDIES), default="heads",
        help="which ablation: heads (pose head x samples loss, 4 runs) or proxies (silhouette, "
        "RGB, edges, 3 runs) (default: heads)",
    )  # fmt: skip
    add_config_arguments(parser)
    arguments = parser.parse_args(argv)
    if arguments.out is None:
        parser.error("--out (the ablation folder) is required")
    base = config_from_arguments(arguments)
    try:
        keep_freed_memory()
        exported = run_ablation(
            base, Path(arguments.out), show_progress=not arguments.quiet, study=arguments.study
        )
    except (FileNotFoundError, ValueError) as error:
        print(f"ablation: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:
        print(f"ablation: {stop}", file=sys.stderr)
        return 130
    poses = f" --poses {base.poses}" if base.poses else ""
    checkpoints = " ".join(str(path) for path in exported.values())
    print(f"ablation finished; compare the {len(exported)} with:")
    print(f"  hkpd-eval {checkpoints}{poses} [--coco COCO_FOLDER]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

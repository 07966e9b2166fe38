"""Calibrate each joint's concentration on held-out synthetic examples, after training.

A trained network's pose distributions can be sharper than its errors warrant for some joints
and wider for others. Run 14 on the synthetic test set, share of true rotations inside the 50 %
/ 90 % most probable regions: hips 0.16 / 0.42 and spine1 0.08 / 0.33 (far too sure), ankles 0.78
/ 0.96 (too unsure), against 0.50 / 0.885 for a calibrated prediction ranked among 25 samples
(:func:`hkpd.evaluation.calibration.calibrated_coverage`). Multiplying a joint's ``F`` by
``t > 0`` keeps its mode and scales its concentration (temperature scaling for rotations, what the
explorer's per-joint sliders do by hand). This tool chooses one ``t`` per joint on the pose
bank's *validation* subjects (never the test subjects the reports use), rendered as the
synthetic test set is (upright, the paper's augmentations), and stores ``log t`` in the
network's ``log_concentration_scale`` buffer
(:class:`hkpd.network.DistributionNetwork`), which acts after the head: the modes, the shape,
the global rotation and the camera are exactly what they were.

Each joint's ``t`` minimises ``(c50 - 0.5)^2 + (c90 - 0.885)^2`` over a grid of ``log2 t`` in
``[-5, 5]`` (steps of 0.25; a tiny pull towards ``t = 1`` decides ties, e.g. for the hands,
whose true rotation is always the rest pose at their mode). Any earlier calibration of the
input is replaced, not compounded.

Usage: ``python -m hkpd.training.calibrate_concentration IN.pt OUT.pt --poses poses.npz``
(then ``hkpd-eval OUT.pt ...``; ``OUT.pt`` is never overwritten; ``--figure calibration.png``
also draws the per-joint coverage before and after).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import torch
from tqdm import tqdm

from hkpd.distributions import KinematicMatrixFisher
from hkpd.evaluation.calibration import calibrated_coverage, truth_rank
from hkpd.kinematic_tree import BODY_JOINT_NAMES, BODY_PARENTS
from hkpd.network.checkpoint import CALIBRATION_KEY, load_network
from hkpd.poses import pose_source
from hkpd.synthesis.generator import SyntheticDataConfig, SyntheticDataGenerator, batch_seed
from hkpd.training.weight_edit_command import save_edited, weight_edit_arguments

LOG2_SCALES = torch.arange(-20, 21) * 0.25
"""The grid of ``log2 t`` tried per joint (``t`` from 1/32 to 32)."""

SAMPLES = 25
"""Samples per example that rank the truth (as ``hkpd-eval``'s coverage)."""

_TIE_PULL = 1e-4
"""Weight of ``(log2 t)^2`` added to the objective: among equally calibrated scales, the one
nearest 1."""


@dataclass(frozen=True)
class JointCalibration:
    """One joint's calibration.

    Attributes:
        joint: body joint name.
        scale: ``t``, the factor on its ``F``.
        before: coverage ``(50 %, 90 %)`` on the validation examples at ``t = 1``.
        after: the same at ``t``.
    """

    joint: str
    scale: float
    before: tuple[float, float]
    after: tuple[float, float]


@torch.no_grad()
def validation_outputs(
    network: torch.nn.Module, poses: Path | None, count: int, seed: int, batch_size: int = 50
) -> tuple[torch.Tensor, torch.Tensor]:
    """The network's uncalibrated ``(count, 23, 3, 3)`` F and the true ``(count, 23, 3, 3)``
    relative rotations of ``count`` upright validation-subject examples (test-set rendering).

    ``network`` must be a :class:`hkpd.network.DistributionNetwork` in eval mode; its
    calibration is set to zero."""
    getattr(network, CALIBRATION_KEY).zero_()
    config = SyntheticDataConfig(
        image_size=int(network.config.image_size), image_proxy=network.config.image_proxy
    )
    generator = SyntheticDataGenerator(pose_source(poses, "val"), config)
    F, truth = [], []
    for index, start in enumerate(tqdm(range(0, count, batch_size), unit="batch")):
        batch = generator.generate(min(batch_size, count - start), batch_seed(seed, index)).batch
        F.append(network(batch.proxy).F.double())
        truth.append(batch.body_pose.double())
    return torch.cat(F), torch.cat(truth)


@torch.no_grad()
def coverage_by_scale(
    F: torch.Tensor, truth: torch.Tensor, log2_scales: torch.Tensor, seed: int = 0
) -> torch.Tensor:
    """``(len(log2_scales), 2, 23)`` share of examples whose true rotation lies in each joint's
    50 % and 90 % region when every ``F`` is multiplied by ``2 ** log2_scale``.

    Args:
        F: ``(N, 23, 3, 3)`` float64 matrix-Fisher parameters.
        truth: ``(N, 23, 3, 3)`` true relative rotations.
        log2_scales: ``(G,)`` the scales tried.
        seed: the sampling seed (the same draws for every scale).
    """
    results = torch.empty(len(log2_scales), 2, F.shape[1], dtype=torch.float64)
    for index, log2_scale in enumerate(tqdm(log2_scales.tolist(), unit="scale")):
        scaled = F * 2.0**log2_scale
        generator = torch.Generator().manual_seed(seed)
        samples = KinematicMatrixFisher(scaled, BODY_PARENTS).sample(SAMPLES, generator=generator)
        ranks = truth_rank(scaled, samples, truth)
        results[index, 0] = (ranks < 0.5 - 1e-9).double().mean(0)
        results[index, 1] = (ranks < 0.9 - 1e-9).double().mean(0)
    return results


def choose_scale_indices(coverage: torch.Tensor, log2_scales: torch.Tensor) -> torch.Tensor:
    """``(23,)`` long: each joint's best entry of ``log2_scales`` ``(G,)``, from
    :func:`coverage_by_scale`'s ``(G, 2, 23)`` coverage."""
    targets = torch.tensor(
        [calibrated_coverage(0.5, SAMPLES), calibrated_coverage(0.9, SAMPLES)],
        dtype=coverage.dtype,
    )
    miss = ((coverage - targets[None, :, None]) ** 2).sum(1)  # (G, 23)
    objective = miss + _TIE_PULL * log2_scales.to(miss.dtype)[:, None] ** 2
    return objective.argmin(0)


def calibrate(
    network: torch.nn.Module, F: torch.Tensor, truth: torch.Tensor
) -> list[JointCalibration]:
    """Choose each joint's scale on ``F`` and ``truth`` (:func:`validation_outputs`) and write
    ``log t`` into ``network``'s calibration buffer."""
    coverage = coverage_by_scale(F, truth, LOG2_SCALES)
    indices = choose_scale_indices(coverage, LOG2_SCALES)
    chosen = LOG2_SCALES[indices]
    at_one = int((LOG2_SCALES == 0).nonzero())
    rows = []
    for joint, at in enumerate(indices.tolist()):
        rows.append(
            JointCalibration(
                BODY_JOINT_NAMES[joint],
                2.0 ** float(chosen[joint]),
                (float(coverage[at_one, 0, joint]), float(coverage[at_one, 1, joint])),
                (float(coverage[at, 0, joint]), float(coverage[at, 1, joint])),
            )
        )
    with torch.no_grad():
        getattr(network, CALIBRATION_KEY).copy_(chosen.float() * math.log(2.0))
    return rows


def main(argv: list[str] | None = None) -> int:
    arguments = weight_edit_arguments(
        argv,
        __doc__.splitlines()[0],
        "trained weights to calibrate",
        "validation examples to calibrate on",
        default_examples=500,
        poses_help="pose bank (its validation split); else procedural",
        figure=True,
    )
    try:
        network, payload = load_network(arguments.checkpoint)
        F, truth = validation_outputs(network, arguments.poses, arguments.examples, arguments.seed)
        rows = calibrate(network, F, truth)
    except (FileNotFoundError, ValueError) as error:
        print(f"calibrate_concentration: error: {error}", file=sys.stderr)
        return 2
    targets = [calibrated_coverage(level, SAMPLES) for level in (0.5, 0.9)]
    print(
        f"{arguments.examples} validation examples, {SAMPLES} samples each; calibrated "
        f"coverage {targets[0]:.3f} / {targets[1]:.3f}"
    )
    print("| joint | scale t | coverage 50 / 90 before | after |\n|---|---|---|---|")
    for row in rows:
        print(
            f"| {row.joint} | {row.scale:.3g} | {row.before[0]:.2f} / {row.before[1]:.2f} "
            f"| {row.after[0]:.2f} / {row.after[1]:.2f} |"
        )
    for name, pick in (("before", lambda r: r.before), ("after", lambda r: r.after)):
        means = [sum(pick(row)[level] for row in rows) / len(rows) for level in (0, 1)]
        print(f"all joints {name}: {means[0]:.3f} / {means[1]:.3f}")
    save_edited(arguments.out, network, payload)
    print(f"wrote {arguments.out}")
    if arguments.figure is not None:
        from hkpd.training.calibration_figure import plot_joint_calibration

        print(f"wrote {plot_joint_calibration(rows, (targets[0], targets[1]), arguments.figure)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""A picture of a per-joint concentration calibration: how often each joint's true rotation
fell inside its 50 % and 90 % regions before and after
(:mod:`hkpd.training.calibrate_concentration`).

One row of bars per joint is easier to scan than the printed table: over-confident joints sit
left of the calibrated lines, under-confident ones right of them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


class CalibratedJoint(Protocol):
    """What the figure reads of one joint
    (:class:`~hkpd.training.calibrate_concentration.JointCalibration`)."""

    joint: str
    scale: float
    before: tuple[float, float]
    after: tuple[float, float]


def plot_joint_calibration(
    rows: Sequence[CalibratedJoint], targets: tuple[float, float], path: Path | str
) -> Path:
    """Two panels (50 % and 90 % regions) of horizontal bars, before and after, per joint.

    Args:
        rows: one entry per joint, in joint order.
        targets: the calibrated coverage at the two levels (0.5 and 0.885 with 25 samples).
        path: where the PNG goes (folders are created).

    Returns:
        The written path.

    Raises:
        ValueError: no rows.
    """
    if not rows:
        raise ValueError("nothing to plot: no joints")
    names = [f"{row.joint} (×{row.scale:.2g})" for row in rows]
    positions = range(len(rows))
    figure, axes = plt.subplots(1, 2, figsize=(10, 0.3 * len(rows) + 1.4), sharey=True)
    for level, (axis, target) in enumerate(zip(axes, targets, strict=True)):
        before = [row.before[level] for row in rows]
        after = [row.after[level] for row in rows]
        axis.barh([p + 0.2 for p in positions], before, height=0.4, color="#bbbbbb", label="before")
        axis.barh([p - 0.2 for p in positions], after, height=0.4, color="#2c7fb8", label="after")
        axis.axvline(target, color="#d95f02", linestyle="--", label=f"calibrated ({target:.3g})")
        axis.set_xlim(0, 1)
        axis.set_title(f"true rotation inside the {(50, 90)[level]} % region")
        axis.set_xlabel("share of validation examples")
    axes[0].set_yticks(list(positions), names, fontsize=8)
    axes[0].invert_yaxis()
    handles, labels = axes[1].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    figure.tight_layout(rect=(0, 0.04, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path

"""A picture of the synthetic test-set comparison: 2D joint error of the mode and of samples.

The paper's ablation question (does a model's *samples* reproject as well as its *mode*?) is
easier to see than to read: one pair of bars per checkpoint, with the gap printed above.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

MODE_KEY = "joint_error_2d_mode"
SAMPLES_KEY = "joint_error_2d_samples"


def plot_2d_errors(rows: dict[str, dict[str, float]], path: Path | str) -> Path:
    """Bar chart of the mode's and the samples' 2D joint errors per checkpoint.

    Args:
        rows: ``{label: metrics}`` as returned by the synthetic evaluation (pixels at 256); each
            metrics dict needs ``joint_error_2d_mode`` and ``joint_error_2d_samples``.
        path: where the PNG goes (folders are created).

    Returns:
        The written path.

    Raises:
        ValueError: no rows, or a row without the two 2D errors.
    """
    if not rows:
        raise ValueError("nothing to plot: no evaluated checkpoints")
    for label, metrics in rows.items():
        missing = {MODE_KEY, SAMPLES_KEY} - set(metrics)
        if missing:
            raise ValueError(f"{label} has no {', '.join(sorted(missing))} to plot")
    labels = [Path(label).stem.replace("_", "\n", 1).replace("_", " ") for label in rows]
    modes = [rows[label][MODE_KEY] for label in rows]
    samples = [rows[label][SAMPLES_KEY] for label in rows]
    positions = range(len(rows))
    figure, axes = plt.subplots(figsize=(1.9 * len(rows) + 2.0, 3.6), dpi=110)
    width = 0.38
    axes.bar([p - width / 2 for p in positions], modes, width, label="mode", color="#3b528b")
    axes.bar([p + width / 2 for p in positions], samples, width, label="samples", color="#5ec962")
    for position, mode, sample in zip(positions, modes, samples, strict=True):
        axes.annotate(
            f"+{100 * (sample / mode - 1):.0f}%",
            (position + width / 2, sample),
            xytext=(0, 3),
            textcoords="offset points",
            ha="center",
            fontsize=8,
        )
    axes.set_xticks(list(positions), labels, fontsize=8)
    axes.set_ylabel("2D joint error (px at 256)")
    axes.set_title("Synthetic test set: mode vs samples (gap above the samples' bar)", fontsize=9)
    axes.set_ylim(0, max(samples) * 1.25)
    axes.legend(fontsize=8, loc="upper left")
    axes.grid(axis="y", alpha=0.3)
    figure.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path

"""Loss and metric curves of a run as a PNG, from its CSV logs."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def read_csv_columns(path: Path) -> dict[str, list[float]]:
    """Numeric columns of a CSV log (empty cells become NaN)."""
    if not path.is_file():
        return {}
    with path.open() as handle:
        rows = list(csv.DictReader(handle))
    columns: dict[str, list[float]] = {}
    for row in rows:
        for key, value in row.items():
            try:
                number = float(value) if value not in ("", None) else math.nan
            except ValueError:
                continue
            columns.setdefault(key, []).append(number)
    return columns


def plot_training_curves(train_csv: Path, val_csv: Path, out: Path) -> Path:
    """Plot every loss term (left) and every validation metric (right) against the step.

    Args:
        train_csv: rows with ``step`` and one column per loss term.
        val_csv: rows with ``step`` and one column per metric (may be missing).
        out: the PNG to write.
    """
    train, val = read_csv_columns(train_csv), read_csv_columns(val_csv)
    figure, (left, right) = plt.subplots(1, 2, figsize=(13, 4.8), dpi=110)
    steps = train.get("step", [])
    for key, values in train.items():
        if key in ("step", "seconds", "samples_per_second", "learning_rate"):
            continue
        left.plot(steps, values, label=key, linewidth=1.2 if key == "total" else 0.8)
    left.set(title="training losses", xlabel="step", ylabel="loss")
    left.grid(alpha=0.3)
    if steps:
        left.legend(fontsize=7, ncol=2)
    val_steps = val.get("step", [])
    shares = {key: values for key, values in val.items() if key.startswith("pose_coverage")}
    for key, values in val.items():
        if key == "step" or key in shares:
            continue
        right.plot(val_steps, values, marker="o", markersize=3, label=key)
    right.set(title="validation (mm for 3D, px at 256 for 2D)", xlabel="step")
    right.grid(alpha=0.3)
    if val_steps:
        right.legend(fontsize=7, ncol=2, loc="upper left")
    if shares:  # calibration shares in [0, 1] on their own axis
        share_axis = right.twinx()
        for key, values in shares.items():
            share_axis.plot(val_steps, values, linestyle="--", marker="s", markersize=3, label=key)
        share_axis.set(ylim=(0, 1), ylabel="share of joints inside the region")
        share_axis.legend(fontsize=7, loc="upper right")
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out)
    plt.close(figure)
    return out

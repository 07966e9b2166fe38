"""Markdown tables of evaluation results."""

from __future__ import annotations

import math

METRIC_LABELS: dict[str, str] = {
    "mpjpe": "MPJPE (mm)",
    "mpjpe_sc": "MPJPE-SC (mm)",
    "mpjpe_pa": "MPJPE-PA (mm)",
    "pve_t_sc": "PVE-T-SC (mm)",
    "joint_error_2d_mode": "2D joint err. mode (px)",
    "joint_error_2d_samples": "2D joint err. samples (px)",
    "joint_spread_2d_samples": "2D sample spread about the mode (px)",
    "diversity_visible": "sample spread, visible joints (mm)",
    "diversity_invisible": "sample spread, invisible joints (mm)",
    "joint_error_2d_mode_box_fraction": "2D joint err. mode (box fraction)",
    "joint_error_2d_samples_box_fraction": "2D joint err. samples (box fraction)",
    "pose_coverage_50": "true pose in 50% region (share of joints)",
    "pose_coverage_90": "true pose in 90% region (share of joints)",
    "keypoint_coverage_2d_50": "annotated keypoint in 50% disc of samples (share)",
    "keypoint_coverage_2d_90": "annotated keypoint in 90% disc of samples (share)",
    "joint_error_2d_detector": "2D joint err. of the detector's input keypoints (px)",
    "people": "people evaluated",
    "cases": "cases",
    "occluded_ratio_median": "hidden limb: uncertainty ratio, median",
    "occluded_ratio_q25": "ratio, 25th pct",
    "occluded_ratio_q75": "ratio, 75th pct",
    "occluded_ratio_median_forearms": "ratio median, forearms",
    "occluded_ratio_median_lower_legs": "ratio median, lower legs",
    "fraction_ratio_at_least_1.5": "share with ratio >= 1.5",
    "other_limbs_change_median": "other limbs: median abs(ratio - 1)",
    "fraction_other_limbs_within_20pct": "other limbs: share within 20%",
    "failed": "no detection",
}
"""Readable names of the metrics; min-of-N columns are named in :func:`label`."""


def label(name: str) -> str:
    """A metric's column header, e.g. ``mpjpe_pa_min_of_10`` -> ``MPJPE-PA min of 10 (mm)``."""
    if name in METRIC_LABELS:
        return METRIC_LABELS[name]
    if "_min_of_" in name:
        base, count = name.split("_min_of_")
        text = METRIC_LABELS.get(base, base)
        return text.replace(" (", f" min of {count} (")
    return name


def markdown_table(rows: dict[str, dict[str, float]], columns: list[str] | None = None) -> str:
    """One row per model/dataset, one column per metric (three significant decimals below 1,
    two below 10, e.g. pixel errors and uncertainty ratios, else one)."""
    if not rows:
        return "(no results)\n"
    columns = columns or list(next(iter(rows.values())))
    header = "| | " + " | ".join(label(c) for c in columns) + " |"
    rule = "|---|" + "---|" * len(columns)
    lines = [header, rule]
    for name, metrics in rows.items():
        cells = []
        for column in columns:
            value = metrics.get(column, math.nan)
            cells.append(_format(value))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _format(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "–"
    if abs(value) < 1:
        return f"{value:.3f}"
    return f"{value:.2f}" if abs(value) < 10 else f"{value:.1f}"


def metrics_table(metrics: dict[str, float]) -> str:
    """One metric per row (for a single model on one dataset)."""
    lines = ["| metric | value |", "|---|---|"]
    lines += [f"| {label(name)} | {value:.2f} |" for name, value in metrics.items()]
    return "\n".join(lines) + "\n"

"""How well a quality score tells off readings from the rest: AUROC and a reliability table.

A reading is *off* when its mode's 2D keypoints lie on average more than :data:`OFF_FRACTION`
of the person's size from the true ones (``hkpd.prediction.quality``). These functions take
``(N,)`` scores in [0, 1] and ``(N,)`` errors (fractions of the person's size) and say how well
the score ranks and how well it is calibrated; ``hkpd-eval --coco`` prints them, and
``docs/experiments/quality_fit.py`` chooses the score's weights with them.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

OFF_FRACTION = 0.2
"""A reading is off when its mode's keypoints are on average further than this share of the
person's size (the annotated box's larger side) from the truth."""

SCORE_BINS = (0.0, 0.2, 0.4, 0.5, 0.6, 0.8, 0.9, 1.0)
"""Edges of the reliability table's score bins (the last bin includes 1)."""

TRUSTED_SCORE = 0.5
"""The threshold the targets name: among readings scored at least this, at most 5 % off."""


def auroc(score: np.ndarray, off: np.ndarray) -> float:
    """How often an off reading scores below a good one, ties counting half (NaN when either
    group is empty). ``score`` ``(N,)``, higher = more trustworthy; ``off`` ``(N,)`` bool."""
    values, bad = np.asarray(score, dtype=np.float64), np.asarray(off, dtype=bool)
    if values.shape != bad.shape:
        raise ValueError(f"score {values.shape} and off {bad.shape} must have the same shape")
    low, high = values[bad], values[~bad]
    if len(low) == 0 or len(high) == 0:
        return math.nan
    below = (low[:, None] < high[None]).mean()
    ties = (low[:, None] == high[None]).mean()
    return float(below + 0.5 * ties)


def off_share_above(score: np.ndarray, off: np.ndarray, threshold: float = TRUSTED_SCORE) -> float:
    """Share of off readings among those scored ``>= threshold`` (NaN when there are none)."""
    values, bad = np.asarray(score, dtype=np.float64), np.asarray(off, dtype=bool)
    kept = values >= threshold
    return float(bad[kept].mean()) if kept.any() else math.nan


def reliability_rows(score: np.ndarray, off: np.ndarray) -> list[dict[str, float]]:
    """One row per :data:`SCORE_BINS` bin holding readings: ``low``, ``high`` (the bin),
    ``count``, ``mean_score`` and ``not_off`` (the share of its readings that are not off; a
    calibrated score has ``not_off`` close to ``mean_score``)."""
    values, bad = np.asarray(score, dtype=np.float64), np.asarray(off, dtype=bool)
    rows = []
    edges = SCORE_BINS
    for index, (low, high) in enumerate(itertools.pairwise(edges)):
        last = index == len(edges) - 2
        inside = (values >= low) & ((values <= high) if last else (values < high))
        if not inside.any():
            continue
        rows.append({
            "low": low, "high": high, "count": float(inside.sum()),
            "mean_score": float(values[inside].mean()), "not_off": float(1 - bad[inside].mean()),
        })  # fmt: skip
    return rows


def quality_summary(score: np.ndarray, error: np.ndarray) -> dict[str, float]:
    """``readings``, ``off`` (count), ``auroc``, ``off_share_at_0.5`` (among readings scored
    >= 0.5), ``share_scored_at_0.5`` and ``expected_calibration_error`` (the count-weighted mean
    gap between each bin's mean score and its not-off share) of ``(N,)`` scores and errors."""
    values = np.asarray(score, dtype=np.float64)
    off = np.asarray(error, dtype=np.float64) > OFF_FRACTION
    rows = reliability_rows(values, off)
    total = max(len(values), 1)
    gap = sum(row["count"] * abs(row["mean_score"] - row["not_off"]) for row in rows) / total
    return {
        "readings": float(len(values)),
        "off": float(off.sum()),
        "auroc": auroc(values, off),
        "off_share_at_0.5": off_share_above(values, off),
        "share_scored_at_0.5": float((values >= TRUSTED_SCORE).mean()) if len(values) else math.nan,
        "expected_calibration_error": float(gap) if len(values) else math.nan,
    }


def quality_table(name: str, score: np.ndarray, error: np.ndarray) -> str:
    """A markdown table of the score against the error for one set of readings: the summary
    line, then the reliability rows."""
    summary = quality_summary(score, error)
    off = np.asarray(error, dtype=np.float64) > OFF_FRACTION
    lines = [
        f"Quality score on {name}: {int(summary['readings'])} readings, {int(summary['off'])} "
        f"off (> {OFF_FRACTION} of the person's size); AUROC {summary['auroc']:.3f}; "
        f"off among scored >= {TRUSTED_SCORE}: {_percent(summary['off_share_at_0.5'])} "
        f"({_percent(summary['share_scored_at_0.5'])} of readings); "
        f"calibration error {summary['expected_calibration_error']:.3f}",
        "",
        "| score bin | readings | mean score | not off |",
        "|---|---|---|---|",
    ]
    for row in reliability_rows(score, off):
        lines.append(
            f"| {row['low']:.1f}-{row['high']:.1f} | {int(row['count'])} | "
            f"{row['mean_score']:.2f} | {row['not_off']:.2f} |"
        )
    return "\n".join(lines)


def _percent(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{100 * value:.1f} %"

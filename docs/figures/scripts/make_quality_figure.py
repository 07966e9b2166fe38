"""The figure of docs/prediction.md "Quality score": how far the score can be trusted.

Reads a cache written by ``docs/experiments/quality_fit.py collect`` and scores its readings
with the shipped rule (:func:`hkpd.prediction.quality.quality_score`). Only readings never used
to choose the rule are drawn: coco_mini val2017 (annotated and detector boxes) and the
held-out synthetic photos (seed 2).

- Left: reliability. Per score bin (the tables' bins,
  :func:`hkpd.evaluation.quality_metrics.reliability_rows`), the share of readings not off
  (mode keypoints within 0.2 of the person's size) against the bin's mean score; a calibrated
  score lies on the diagonal. Marker area ~ readings in the bin.
- Right: every reading's score, off readings (red) and the rest (grey), one row per set, with
  the warning threshold 0.5.

    python docs/figures/scripts/make_quality_figure.py q.npz --out docs/figures/quality_score.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hkpd.evaluation.quality_metrics import OFF_FRACTION, auroc, reliability_rows
from hkpd.prediction.quality import LOW_SCORE, SCORE_SIGNALS, quality_score

SETS = {
    "coco_mini val2017": lambda source: np.char.startswith(source, "val2017"),
    "synthetic, held out": lambda source: source == "synthetic_held_out",
}
"""The sets drawn, each a test on the cache's ``source`` column."""

COLOURS = ("#1f5fa8", "#d98c1f")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cache", type=Path)
    parser.add_argument("--out", type=Path, default=Path("docs/figures/quality_score.png"))
    args = parser.parse_args()
    data = np.load(args.cache)
    names = [str(name) for name in data["signal_names"]]
    score = quality_score(data["signals"][:, [names.index(name) for name in SCORE_SIGNALS]])
    source, good = data["source"].astype(str), data["error"] <= OFF_FRACTION
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), width_ratios=(1, 1.4))
    left.plot([0, 1], [0, 1], color="0.7", lw=1, ls="--", label="calibrated")
    for row, ((label, test), colour) in enumerate(zip(SETS.items(), COLOURS, strict=True)):
        rows = test(source)
        bins = reliability_rows(score[rows], ~good[rows])
        points = [(row["mean_score"], row["not_off"], row["count"]) for row in bins]
        ranking = auroc(score[rows], ~good[rows])
        left.plot([p[0] for p in points], [p[1] for p in points], color=colour, lw=1, marker="o",
                  markersize=4, label=f"{label} (AUROC {ranking:.2f})")  # fmt: skip
        sizes = [12 * p[2] ** 0.9 for p in points]
        left.scatter([p[0] for p in points], [p[1] for p in points], s=sizes, color=colour,
                     alpha=0.5)  # fmt: skip
        jitter = np.random.default_rng(row).uniform(-0.18, 0.18, rows.sum())
        off = ~good[rows]
        right.scatter(score[rows][~off], row + jitter[~off], s=10, color="0.6", alpha=0.6,
                      label="not off" if row == 0 else None)  # fmt: skip
        right.scatter(score[rows][off], row + jitter[off], s=22, color="#c0392b",
                      label="off (> 0.2 of the person's size)" if row == 0 else None)  # fmt: skip
        share = off[score[rows] >= LOW_SCORE].mean()
        caption = f"{rows.sum()} readings, {off.sum()} off\n"
        caption += f"{100 * share:.0f} % off at ≥ {LOW_SCORE}"
        right.text(1.02, row, caption, va="center", fontsize=8)
    left.set(xlim=(0, 1), ylim=(0, 1.02), xlabel="mean score in the bin",
             ylabel="share of readings not off", title="Reliability")  # fmt: skip
    left.legend(fontsize=8, loc="lower right")
    left.text(0.02, 0.95, "marker area ~ readings in the bin", fontsize=8, color="0.4")
    right.axvline(LOW_SCORE, color="0.3", lw=1, ls=":")
    right.text(LOW_SCORE - 0.01, 1.45, "warning below", ha="right", fontsize=8, color="0.3")
    right.set(xlim=(0, 1), ylim=(-0.5, 1.6), yticks=range(len(SETS)), yticklabels=list(SETS),
              xlabel="quality score", title="Every reading's score")  # fmt: skip
    right.legend(fontsize=8, loc="upper right")
    figure.suptitle("Quality score on readings never used to choose it", fontsize=11)
    figure.tight_layout()
    figure.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

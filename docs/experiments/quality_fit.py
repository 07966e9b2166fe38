"""Choose the quality score's weights and measure them (issue 51; docs/prediction.md, "Quality
score").

1. ``collect``: read coco_mini people (through the annotated box grown by 15 % and through the
   detector's own person boxes, :mod:`hkpd.evaluation.quality_data`) and synthetic photos with
   hard cases (``--synthetic`` photos for fitting, seed 1; ``--held-out`` photos, seed 2), with
   the shipped predictor; write every reading's signals and error to ``--cache`` (an ``.npz``).
2. ``fit``: an L2-penalised logistic regression of "not off" on the standardised candidate
   signals (``hkpd.prediction.quality.SIGNAL_DIRECTIONS``, each with the sign its weight must
   have: a score must not rise with a worse signal), fitted on coco_mini **train2017** and the
   seed-1 synthetic readings only (each source weighted to the same total, so the few real
   readings count as much as the many synthetic ones). A signal whose weight comes out against
   its meaning is dropped and the rest are fitted again, until every sign agrees. A signal not
   measured (NaN) counts as the fitting data's mean. Prints the constants to paste into
   ``core/prediction/quality.py`` (``SCORE_SIGNALS`` included) and, for every source, the
   AUROC, the share off among readings scored >= 0.5 and the reliability table
   (:mod:`hkpd.evaluation.quality_metrics`), with the
   weights in the cache's own scores (the shipped ones) too.

    python docs/experiments/quality_fit.py collect ../shared/data/coco_mini --cache q.npz
    python docs/experiments/quality_fit.py fit --cache q.npz
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from hkpd.evaluation.quality_data import coco_readings, synthetic_readings
from hkpd.evaluation.quality_metrics import OFF_FRACTION, auroc, quality_summary, quality_table
from hkpd.prediction import Predictor
from hkpd.prediction.quality import (
    READERS_DISPUTED_SHARE,
    READERS_TORSO_OFFSET,
    SCORE_SIGNALS,
    SIGNAL_DIRECTIONS,
    SIGNAL_NAMES,
    SWAP_GAIN,
    WARNING_FLAGS,
    quality_score,
)

FIT_SOURCES = ("train2017/annotated", "train2017/detector", "synthetic")
PENALTY = 1.0
READER_FLAG_CANDIDATES = {
    "readers_disputed_share": (0.2, 0.25, 0.3, 0.35, 0.4, 0.5),
    "readers_torso_offset": (0.1, 0.15, 0.2, 0.25, 0.3, 0.4),
    "readers_swap_gain": (0.0, 0.02, 0.05, 0.1, 0.15),
}
"""Thresholds tried for the reader flags (step 3 of ``fit``): ``readers_disagree`` is raised by
the disputed share or the torso offset, ``left_right_unsure`` by the swap gain."""


def reader_flags(signals: np.ndarray, names: list[str]) -> np.ndarray:
    """``(N, 2)`` bool: ``readers_disagree`` and ``left_right_unsure`` of ``(N, S)`` signals at
    the shipped thresholds (NaN signals raise nothing)."""
    column = {name: signals[:, names.index(name)] for name in READER_FLAG_CANDIDATES}
    with np.errstate(invalid="ignore"):
        disagree = (column["readers_disputed_share"] > READERS_DISPUTED_SHARE) | (
            column["readers_torso_offset"] > READERS_TORSO_OFFSET
        )
        return np.stack([disagree, column["readers_swap_gain"] > SWAP_GAIN], axis=1)


def not_warned(score: np.ndarray, flags: np.ndarray, signals: np.ndarray, names) -> np.ndarray:
    """``(N,)`` bool: readings ``posterior.quality.low`` would not warn about: score >= 0.5, no
    other warning flag of the cache and no reader flag at the shipped thresholds (the cache's
    reader flags were raised at the thresholds of its day)."""
    others = WARNING_FLAGS - {"readers_disagree", "left_right_unsure"}  # recomputed below
    cached = np.array([not others.isdisjoint(str(f).split("|")) for f in flags])
    return (score >= 0.5) & ~cached & ~reader_flags(signals, names).any(1)


def reader_flag_table(signals, error, rows, names) -> None:
    """For each reader signal and threshold: readings over it and the share of them off, on
    the fitting readings (``rows``): a flag warns when more than a third of its readings are
    off (twice the fitting data's off share)."""
    off = error[rows] > OFF_FRACTION
    print(f"\nReader flag thresholds (fitting readings: {rows.sum()}, {off.mean():.1%} off):")
    for name, candidates in READER_FLAG_CANDIDATES.items():
        values = signals[rows, names.index(name)]
        cells = []
        for threshold in candidates:
            over = np.nan_to_num(values, nan=-np.inf) > threshold
            share = off[over].mean() if over.any() else float("nan")
            cells.append(f"> {threshold}: {over.sum()} ({share:.0%} off)")
        print(f"- {name}: " + ", ".join(cells))


def collect(coco: Path, cache: Path, synthetic: int, held_out: int) -> None:
    """Read everything (module docstring, step 1) and write ``cache``."""
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    readings = coco_readings(predictor, coco, "annotated")
    readings += coco_readings(predictor, coco, "detector")
    readings += synthetic_readings(predictor, synthetic, seed=1)
    held = synthetic_readings(predictor, held_out, seed=2)
    readings += [replace(reading, source="synthetic_held_out") for reading in held]
    predictor.close()
    np.savez(
        cache,
        source=np.array([r.source for r in readings]),
        name=np.array([r.name for r in readings]),
        signals=np.stack([r.signals for r in readings]),
        error=np.array([r.error for r in readings]),
        flags=np.array(["|".join(r.flags) for r in readings]),
        signal_names=np.array(SIGNAL_NAMES),
    )
    print(f"{len(readings)} readings written to {cache}")


def logistic(features: np.ndarray, good: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Weights (bias first) of a weighted L2-penalised logistic regression, by Newton steps."""
    design = np.c_[np.ones(len(features)), features]
    weights = np.zeros(design.shape[1])
    ridge = PENALTY * np.diag(np.r_[0.0, np.ones(design.shape[1] - 1)])
    for _ in range(100):
        p = 1 / (1 + np.exp(-design @ weights))
        gradient = design.T @ (weight * (p - good)) + ridge @ weights
        hessian = design.T @ (design * (weight * p * (1 - p))[:, None]) + ridge
        step = np.linalg.solve(hessian, gradient)
        weights -= step
        if np.abs(step).max() < 1e-10:
            break
    return weights


def agreeing_fit(
    signals: np.ndarray, good: np.ndarray, weight: np.ndarray, names: list[str]
) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """The candidate signals kept, their means and spreads, and the weights (bias first) once
    every weight's sign agrees with :data:`SIGNAL_DIRECTIONS` (module docstring, step 2).

    ``signals``: ``(N, S)`` fitting readings' signals (``names`` order); ``good``: ``(N,)`` 1
    when not off; ``weight``: ``(N,)`` each reading's weight."""
    kept = [name for name in SIGNAL_DIRECTIONS if name in names]
    while True:
        columns = signals[:, [names.index(name) for name in kept]]
        mean = np.nanmean(columns, 0)
        spread = np.nanstd(columns, 0) + 1e-6
        standard = np.nan_to_num((columns - mean) / spread)
        weights = logistic(standard, good, weight)
        signs = [SIGNAL_DIRECTIONS[name] for name in kept]
        against = {n: -w * sign for n, w, sign in zip(kept, weights[1:], signs, strict=True)}
        worst = max(against, key=against.get)
        if against[worst] <= 0:
            return kept, mean, spread, weights
        wrong = -against[worst] * SIGNAL_DIRECTIONS[worst]
        print(f"dropped {worst}: its weight {wrong:+.3f} is against its meaning")
        kept.remove(worst)


def fit(cache: Path) -> None:
    """Fit on the fitting sources, print the constants and every source's table."""
    data = np.load(cache)
    source, every, error = data["source"], data["signals"], data["error"]
    names = [str(name) for name in data["signal_names"]]
    chosen = np.isin(source, FIT_SOURCES)
    weight = np.zeros(len(source))
    for name in FIT_SOURCES:
        rows = source == name
        weight[rows] = chosen.sum() / (len(FIT_SOURCES) * max(rows.sum(), 1))
    good = (error[chosen] <= OFF_FRACTION).astype(float)
    kept, mean, spread, weights = agreeing_fit(every[chosen], good, weight[chosen], names)
    signals = every[:, [names.index(name) for name in kept]]
    standard = np.nan_to_num((signals - mean) / spread)
    print("SCORE_SIGNALS = (" + ", ".join(f'"{name}"' for name in kept) + ")")
    print("QUALITY_MEAN = (" + ", ".join(f"{v:.4g}" for v in mean) + ")")
    print("QUALITY_SPREAD = (" + ", ".join(f"{v:.4g}" for v in spread) + ")")
    print("QUALITY_WEIGHTS = (" + ", ".join(f"{v:.4g}" for v in weights) + ")")
    logits = weights[0] + standard @ weights[1:]
    fitted = 1 / (1 + np.exp(-logits))
    shipped = quality_score(every[:, [names.index(name) for name in SCORE_SIGNALS]])
    reader_flag_table(every, error, chosen, names)
    print("\n| source | readings | off | AUROC (fitted) | off at >= 0.5 | off not warned | "
          "warned | AUROC (shipped) | off at >= 0.5 (shipped) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    quiet = not_warned(fitted, data["flags"], every, names)
    groups = {name: source == name for name in sorted(set(source.tolist()))}
    groups["val2017 (both boxes)"] = np.char.startswith(source.astype(str), "val2017")
    for name, rows in groups.items():
        now, before = (
            quality_summary(fitted[rows], error[rows]),
            quality_summary(shipped[rows], error[rows]),
        )
        off_quiet = (error[rows & quiet] > OFF_FRACTION).mean() if (rows & quiet).any() else 0.0
        print(f"| {name} | {int(now['readings'])} | {int(now['off'])} | {now['auroc']:.3f} | "
              f"{now['off_share_at_0.5']:.3f} | {off_quiet:.3f} | {1 - quiet[rows].mean():.2f} | "
              f"{before['auroc']:.3f} | {before['off_share_at_0.5']:.3f} |")  # fmt: skip
    for name, rows in groups.items():
        print("\n" + quality_table(f"{name} (shipped weights)", shipped[rows], error[rows]))
    print("\nSingle signals' AUROC (higher signal = better):")
    mean_of = np.nanmean(every[chosen], 0)
    for name in sorted(set(source.tolist())):
        rows = source == name
        off = error[rows] > OFF_FRACTION
        cells = ", ".join(
            f"{signal} {auroc(np.nan_to_num(every[rows, i], nan=mean_of[i]), off):.2f}"
            for i, signal in enumerate(names)
        )
        print(f"- {name}: {cells}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("step", choices=("collect", "fit"))
    parser.add_argument("coco", type=Path, nargs="?")
    parser.add_argument("--cache", type=Path, required=True)
    parser.add_argument("--synthetic", type=int, default=320)
    parser.add_argument("--held-out", type=int, default=160)
    args = parser.parse_args(argv)
    if args.step == "collect":
        if args.coco is None:
            parser.error("collect needs the coco_mini folder")
        collect(args.coco, args.cache, args.synthetic, args.held_out)
    else:
        fit(args.cache)


if __name__ == "__main__":
    main()

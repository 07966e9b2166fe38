"""``hkpd-eval --shape``'s record (``shape.json``) and its markdown tables.

``shape.json`` holds, for each posterior evaluated on the synthetic test set (``"network"``,
and ``"evidence"`` with ``--evidence``), :meth:`hkpd.evaluation.shape_metrics.ShapeScores.as_dict`
(``r2`` and ``z2``: 10 floats each; ``pve_t_mm``, ``pve_t_sc_mm``, ``mean_body_pve_t_sc_mm``,
``height_error_mm``, ``mean_body_height_error_mm``; ``examples``); with ``--coco`` a ``"coco"`` key,
``{split: {posterior: {"mode_iou", "average_shape_iou", "people"}, "detector_iou": float or
null}}`` for each photo folder (``val2017``, ``train2017``) and ``"all"``; and ``"settings"``
(the checkpoint, the example count, the mask noise).
"""

from __future__ import annotations

import math

from hkpd.evaluation.report import markdown_table
from hkpd.evaluation.shape_metrics import ShapeScores

ShapeRecord = dict[str, object]
"""The JSON-ready content of ``shape.json``."""


def _mean(values: list[float]) -> float:
    return sum(values) / len(values) if values else math.nan


def shape_summary_row(scores: ShapeScores) -> dict[str, float]:
    """The headline numbers of one posterior's :class:`ShapeScores`, by readable column."""
    rest_r2, rest_z2 = scores.r2[1:], scores.z2[1:]
    return {
        "R² β₀": scores.r2[0],
        "mean R² β₁…β₉": _mean(rest_r2),
        "max R² β₁…β₉": max(rest_r2, default=math.nan),
        "PVE-T (mm)": scores.pve_t_mm,
        "PVE-T-SC (mm)": scores.pve_t_sc_mm,
        "mean body PVE-T-SC (mm)": scores.mean_body_pve_t_sc_mm,
        "height err. (mm)": scores.height_error_mm,
        "mean body height err. (mm)": scores.mean_body_height_error_mm,
        "z² β₀": scores.z2[0],
        "z² β₁…β₉ min": min(rest_z2, default=math.nan),
        "z² β₁…β₉ max": max(rest_z2, default=math.nan),
        "examples": float(scores.examples),
    }


def shape_markdown(scores: dict[str, ShapeScores], title: str) -> str:
    """The summary table and the per-coefficient R² and z² table of every posterior."""
    summary = {name: shape_summary_row(score) for name, score in scores.items()}
    per_coefficient = {}
    for name, score in scores.items():
        per_coefficient[f"{name}: R²"] = {f"β{i}": v for i, v in enumerate(score.r2)}
        per_coefficient[f"{name}: z²"] = {f"β{i}": v for i, v in enumerate(score.z2)}
    return (
        f"### {title}\n\n"
        + markdown_table(summary)
        + "\nPer coefficient (R²: 1 - var(mean - true) / var(true); z²: mean of "
        "(mean - true)² / std², 1 when the std is honest):\n\n" + markdown_table(per_coefficient)
    )


def coco_markdown(coco: dict[str, dict[str, object]], title: str) -> str:
    """The silhouette IoU table: one row per split and posterior."""
    rows: dict[str, dict[str, float]] = {}
    for split, entry in coco.items():
        detector = entry.get("detector_iou")
        for name, value in entry.items():
            if not isinstance(value, dict):
                continue
            rows[f"{split}, {name}"] = {
                "mode IoU": float(value["mode_iou"]),
                "average-shape IoU": float(value["average_shape_iou"]),
                "mode - average": float(value["mode_iou"]) - float(value["average_shape_iou"]),
                "BlazePose mask IoU": math.nan if detector is None else float(detector),
                "people": float(value["people"]),
            }
    return f"### {title}\n\n" + markdown_table(rows)


def sex_markdown(record: dict, title: str) -> str:
    """The sex, measurement and stated-values tables of
    :func:`hkpd.evaluation.sex_shape_eval.evaluate_sex_shape`'s record (empty without one)."""
    if "sex" not in record:
        return ""
    sex, stated = record["sex"], record["stated"]
    summary = {
        "automatic sex": {"PVE-T-SC mm": sex["pve_t_sc_mm"], "sex accuracy": sex["accuracy"],
                          "sex ECE": sex["ece"]},
        "sex stated": {"PVE-T-SC mm": stated["sex"]["pve_t_sc_mm"]},
        "sex, height, mass stated": {"PVE-T-SC mm": stated["sex+height+mass"]["pve_t_sc_mm"]},
        "mean body": {"PVE-T-SC mm": record["mean_body_pve_t_sc_mm"]},
    }  # fmt: skip
    measurements = {
        name: {"MAE": values["mae"], "z²": values["z2"]}
        for name, values in record["measurements"].items()
    }
    return (
        f"### {title}\n\n" + markdown_table(summary)
        + "\nMeasurements under the automatic posterior (MAE in metres or kg; z² 1 when the "
        "std is honest):\n\n" + markdown_table(measurements)
    )  # fmt: skip

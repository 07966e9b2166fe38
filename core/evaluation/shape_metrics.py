"""How well a posterior reads the body's shape: per-coefficient R² and calibration, T-pose errors.

For a set of examples with known shape coefficients ``true (N, K)`` and a predicted shape
Gaussian per example (``mean (N, K)``, ``std (N, K)``):

- **R²** per coefficient: ``1 - var(mean - true) / var(true)`` over the examples (1: read
  exactly; 0: no better than a constant; below 0: worse than one). The variances are the
  population variances (``unbiased=False``), so a constant prediction at the true mean scores 0.
- **z²** per coefficient: the mean of ``(mean - true)² / std²`` (about 1 when the std is honest,
  above 1 when over-confident, below when under-confident).
- **PVE-T** (:func:`pve_t`): per-vertex distance of the T-pose bodies with no alignment, and
  **PVE-T-SC** (:func:`hkpd.evaluation.metrics.pve_t_sc`) after the STRAPS scale correction,
  also of the mean body (all coefficients 0) for reference.
- **Height error**: absolute difference of the T-pose bodies' vertical extents (SMPL's y axis
  is up in the rest pose).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.body import BodyModel
from hkpd.evaluation.metrics import MILLIMETRES_PER_METRE, pve_t_sc

UP_AXIS = 1
"""The vertical axis of SMPL's rest pose (y)."""


def r_squared(predicted: torch.Tensor, true: torch.Tensor) -> torch.Tensor:
    """Per-coefficient R² of ``predicted (N, K)`` against ``true (N, K)``; ``(K,)``.

    Raises:
        ValueError: shapes differ or fewer than 2 examples.
    """
    _check_pairs(predicted, true)
    residual = (predicted - true).var(0, unbiased=False)
    return 1.0 - residual / true.var(0, unbiased=False)


def z_squared(mean: torch.Tensor, std: torch.Tensor, true: torch.Tensor) -> torch.Tensor:
    """Per-coefficient mean of ``(mean - true)² / std²`` over ``N`` examples; ``(K,)``.

    Args:
        mean, std, true: ``(N, K)``; ``std`` positive.
    """
    _check_pairs(mean, true)
    if std.shape != true.shape:
        raise ValueError(f"std must be {tuple(true.shape)}, got {tuple(std.shape)}")
    return ((mean - true) / std).square().mean(0)


def pve_t(predicted_vertices: torch.Tensor, target_vertices: torch.Tensor) -> torch.Tensor:
    """Mean per-vertex distance of T-pose vertices ``(B, V, 3)`` with no alignment; ``(B,)``,
    the vertices' units."""
    return (predicted_vertices - target_vertices).norm(dim=-1).mean(-1)


def body_height(vertices: torch.Tensor) -> torch.Tensor:
    """Vertical extent of T-pose vertices ``(B, V, 3)`` (SMPL: y up); ``(B,)``, their units."""
    heights = vertices[..., UP_AXIS]
    return heights.amax(-1) - heights.amin(-1)


@dataclass(frozen=True)
class ShapeScores:
    """The shape scores of one posterior on a set of examples (see the module's definitions).

    Attributes:
        r2: ``K`` floats, R² of the shape mean per coefficient.
        z2: ``K`` floats, mean squared error in units of the predicted std per coefficient.
        pve_t_mm: PVE-T of the shape mean, millimetres.
        pve_t_sc_mm: PVE-T-SC of the shape mean, millimetres.
        mean_body_pve_t_sc_mm: PVE-T-SC of the mean body (all coefficients 0), millimetres.
        height_error_mm: mean absolute height error of the shape mean, millimetres.
        mean_body_height_error_mm: the same of the mean body, millimetres.
        examples: how many examples were scored.
    """

    r2: list[float]
    z2: list[float]
    pve_t_mm: float
    pve_t_sc_mm: float
    mean_body_pve_t_sc_mm: float
    height_error_mm: float
    mean_body_height_error_mm: float
    examples: int

    def as_dict(self) -> dict[str, list[float] | float | int]:
        """The scores by name, as ``shape.json`` stores them."""
        return {
            "r2": self.r2,
            "pve_t_mm": self.pve_t_mm,
            "pve_t_sc_mm": self.pve_t_sc_mm,
            "mean_body_pve_t_sc_mm": self.mean_body_pve_t_sc_mm,
            "height_error_mm": self.height_error_mm,
            "z2": self.z2,
            "mean_body_height_error_mm": self.mean_body_height_error_mm,
            "examples": self.examples,
        }


@torch.no_grad()
def shape_scores(
    body: BodyModel, mean: torch.Tensor, std: torch.Tensor, true: torch.Tensor
) -> ShapeScores:
    """Score predicted shape Gaussians against the true coefficients.

    Args:
        body: the body model (for the T-pose meshes; its device and dtype are used).
        mean, std, true: ``(N, K)`` predicted mean and std, and true coefficients.
    """
    _check_pairs(mean, true)
    parameter = next(iter(body.buffers()))
    mean, true = (t.to(parameter.device, parameter.dtype) for t in (mean, true))
    predicted, target = body.tpose(mean), body.tpose(true)
    average = body.tpose(torch.zeros_like(true))
    millimetres = MILLIMETRES_PER_METRE
    true_height = body_height(target)
    height = (body_height(predicted) - true_height).abs()
    average_height = (body_height(average) - true_height).abs()
    return ShapeScores(
        r2=[float(v) for v in r_squared(mean, true)],
        z2=[float(v) for v in z_squared(mean, std.to(mean), true)],
        pve_t_mm=float(pve_t(predicted, target).mean()) * millimetres,
        pve_t_sc_mm=float(pve_t_sc(predicted, target).mean()) * millimetres,
        mean_body_pve_t_sc_mm=float(pve_t_sc(average, target).mean()) * millimetres,
        height_error_mm=float(height.mean()) * millimetres,
        mean_body_height_error_mm=float(average_height.mean()) * millimetres,
        examples=int(true.shape[0]),
    )


def _check_pairs(predicted: torch.Tensor, true: torch.Tensor) -> None:
    if predicted.shape != true.shape or true.dim() != 2:
        raise ValueError(
            f"expected two (N, K) tensors, got {tuple(predicted.shape)} and {tuple(true.shape)}"
        )
    if true.shape[0] < 2:
        raise ValueError(f"R² needs at least 2 examples, got {true.shape[0]}")

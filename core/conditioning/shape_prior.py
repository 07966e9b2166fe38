"""The fit's shape prior for one sex: the network's reading re-based on that sex's population,
then conditioned on what the user states (``docs/shape.md``, "Sex and measurements").

The network learnt to read shape against training bodies drawn from ``N(0, s_t² I)``
(:data:`TRAINING_SHAPE_STD`), so what its Gaussian ``N(μ_n, diag σ_n²)`` says *about the
photo* is the ratio ``ℓ(β) = N(β; μ_n, σ_n²) / N(β; 0, s_t²)``: per coefficient a precision
``λ = max(1/σ_n² - 1/s_t², 0)`` and a linear term ``h = μ_n/σ_n²`` (zero where ``λ`` is).
Tempered by the fit's prior weight ``w`` (the network is over-confident; the population is
not), the shape prior of sex ``s`` with population ``N(m_s, C_s)`` is

    p_s(β) ∝ ℓ(β)^w N(β; m_s, C_s),    precision  P = w diag λ + C_s⁻¹,   P μ = w h + C_s⁻¹ m_s,

and its weight ``log Z_s = log ∫ ℓ^w N(m_s, C_s)`` (up to a constant shared by both sexes) is
how well that population explains the network's reading. A stated measurement
``v ± σ_v`` is a Gaussian observation of ``m(β)`` (:class:`hkpd.body.BodyMeasurer`): linear
for height and shoulder width, linearised (and re-linearised at the updated mean) for the
others; it updates ``(μ, Σ)`` in closed form and adds ``log N(v; m(μ), J Σ Jᵀ + σ_v²)`` to the
weight, so a stated height also says which sex is likelier.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import torch

from hkpd.body.measurements import MEASUREMENT_NAMES

TRAINING_SHAPE_STD = 1.25
"""Standard deviation of the shape coefficients the network was trained on
(``hkpd.synthesis.SynthesisConfig.shape_std``): the population its reading is relative to."""

RELINEARISATIONS = 3
"""Passes of the stated-measurement update (the nonlinear ones are linearised at the mean of the
previous pass; three move the mean by under 1e-6 of a coefficient on mass)."""


class MeasureFunction(Protocol):
    """What :func:`conditioned_on_measurements` needs of a measurer
    (:class:`hkpd.body.measurements.BodyMeasurer` is one)."""

    def __call__(self, betas: torch.Tensor) -> torch.Tensor:
        """``(N, K)`` shapes -> ``(N, 6)`` measurements."""
        ...

    def jacobian(self, betas: torch.Tensor) -> torch.Tensor:
        """``(K,)`` shape -> ``(6, K)`` derivatives."""
        ...


@dataclass(frozen=True)
class ShapeGaussian:
    """A full-covariance Gaussian over shape coefficients for each of ``B`` starts.

    Attributes:
        mean: ``(B, K)``.
        covariance: ``(B, K, K)`` symmetric positive definite.
        log_weight: ``(B,)`` log of the integral of the unnormalised product it came from
            (the evidence of the population and the stated values; comparable across sexes).
    """

    mean: torch.Tensor
    covariance: torch.Tensor
    log_weight: torch.Tensor

    def rows(self, index: torch.Tensor | slice | int) -> ShapeGaussian:
        """The starts ``index`` (an int keeps a batch of one)."""
        if isinstance(index, int):
            index = slice(index, index + 1)
        return ShapeGaussian(self.mean[index], self.covariance[index], self.log_weight[index])

    def concatenated(self, other: ShapeGaussian) -> ShapeGaussian:
        """These starts, then ``other``'s."""
        return ShapeGaussian(
            torch.cat((self.mean, other.mean)),
            torch.cat((self.covariance, other.covariance)),
            torch.cat((self.log_weight, other.log_weight)),
        )

    def precision_root(self) -> torch.Tensor:
        """``(B, K, K)`` ``R`` with ``Rᵀ R = Σ⁻¹`` (``R = L⁻¹``, ``Σ = L Lᵀ``): the fit's shape
        residual is ``R (β - mean)``."""
        lower = torch.linalg.cholesky(self.covariance)
        eye = torch.eye(lower.shape[-1], dtype=lower.dtype, device=lower.device)
        return torch.linalg.solve_triangular(lower, eye.expand_as(lower), upper=False)

    def log_det_precision(self) -> torch.Tensor:
        """``(B,)`` ``log det Σ⁻¹``."""
        return -torch.linalg.slogdet(self.covariance)[1]


def rebased_on_population(
    shape_mean: torch.Tensor,
    shape_std: torch.Tensor,
    population_mean: torch.Tensor,
    population_covariance: torch.Tensor,
    prior_weight: float,
) -> ShapeGaussian:
    """The network's shape reading of ``B`` starts re-based on one population (module
    docstring).

    Args:
        shape_mean, shape_std: ``(B, K)`` the network's shape Gaussians.
        population_mean: ``(K,)``; population_covariance: ``(K, K)`` (e.g. one sex's prior).
        prior_weight: the fit's temperature ``w`` on the network (``EvidenceConfig``).

    Returns:
        float64 :class:`ShapeGaussian` with ``log_weight = log Z`` (shared constants dropped).
    """
    mean, std = shape_mean.double(), shape_std.double()
    m = population_mean.double().to(mean.device)
    cov = population_covariance.double().to(mean.device)
    floor = 1.0 / TRAINING_SHAPE_STD**2
    precision_seen = (1.0 / std**2 - floor).clamp_min(0.0)
    linear_seen = torch.where(precision_seen > 0, mean / std**2, torch.zeros_like(mean))
    population_precision = torch.linalg.inv(cov)
    precision = torch.diag_embed(prior_weight * precision_seen) + population_precision
    linear = prior_weight * linear_seen + population_precision @ m
    covariance = _symmetric(torch.linalg.inv(precision))
    posterior_mean = (covariance @ linear[..., None])[..., 0]
    # log ∫ exp(-½βᵀΛβ + hᵀβ) N(β; m, C) dβ = ½ ηᵀP⁻¹η - ½ log det P - ½ log det C - ½ mᵀC⁻¹m
    log_weight = 0.5 * (
        (linear * posterior_mean).sum(-1)
        - torch.linalg.slogdet(precision)[1]
        - torch.linalg.slogdet(cov)[1]
        - m @ population_precision @ m
    )
    return ShapeGaussian(posterior_mean, covariance, log_weight)


def conditioned_on_measurements(
    prior: ShapeGaussian,
    measure: MeasureFunction,
    stated: Mapping[str, tuple[float, float]],
) -> ShapeGaussian:
    """``prior`` updated by stated measurements ``{name: (value, std)}`` (module docstring).

    Args:
        prior: ``B`` Gaussians.
        measure: ``(N, K) -> (N, 6)`` measurements (:class:`hkpd.body.BodyMeasurer`) with a
            ``jacobian((K,)) -> (6, K)``.
        stated: values in metres / kilograms with their standard deviations; names from
            :data:`hkpd.body.measurements.MEASUREMENT_NAMES`.
    """
    if not stated:
        return prior
    columns = [MEASUREMENT_NAMES.index(name) for name in stated]
    values = torch.tensor([float(stated[name][0]) for name in stated], dtype=torch.float64)
    noise = torch.diag(torch.tensor([float(stated[name][1]) for name in stated]) ** 2).double()
    rows = []
    for row in range(prior.mean.shape[0]):
        rows.append(_condition_one(prior.rows(row), measure, columns, values, noise))
    mean, covariance, log_weight = (torch.cat(parts) for parts in zip(*rows, strict=True))
    return ShapeGaussian(mean, covariance, log_weight)


def _condition_one(
    prior: ShapeGaussian,
    measure: MeasureFunction,
    columns: list[int],
    values: torch.Tensor,
    noise: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """One start's iterated-linearisation update: ``(mean (1, K), covariance (1, K, K),
    log_weight (1,))``."""
    mean0, cov0 = prior.mean[0].cpu(), prior.covariance[0].cpu()
    mean = mean0
    for _ in range(RELINEARISATIONS):
        jacobian = measure.jacobian(mean)[columns]  # (M, K)
        predicted = measure(mean[None])[0, columns] + jacobian @ (mean0 - mean)
        innovation_cov = _symmetric(jacobian @ cov0 @ jacobian.T + noise)
        gain = cov0 @ jacobian.T @ torch.linalg.inv(innovation_cov)
        mean = mean0 + gain @ (values - predicted)
    covariance = _symmetric(cov0 - gain @ jacobian @ cov0)
    residual = values - predicted
    log_likelihood = -0.5 * (
        residual @ torch.linalg.solve(innovation_cov, residual)
        + torch.linalg.slogdet(innovation_cov)[1]
        + len(columns) * math.log(2 * math.pi)
    )
    device = prior.mean.device
    return (
        mean[None].to(device),
        covariance[None].to(device),
        (prior.log_weight + log_likelihood.to(device)),
    )


def _symmetric(matrix: torch.Tensor) -> torch.Tensor:
    return 0.5 * (matrix + matrix.transpose(-1, -2))

"""Sex as a discrete latent of the body posterior (``docs/shape.md``, "Sex and measurements").

A blend of a man and a woman is not a plausible person, so the shape prior is a two-component
mixture: for each sex the network's shape reading is re-based on that sex's population prior
(stored with the body model) and conditioned on any stated measurements, the keypoint fit runs
once per sex, and each sex's posterior probability comes from the fits' Laplace evidence
(:attr:`hkpd.conditioning.KeypointFit.log_evidence`): a principled model comparison that costs
one more fit. The mode and the drawn body are the more probable sex's; samples come from the
mixture (shape per sample from its drawn sex, pose from the more probable sex's fit: the two
fits' poses differ by a fraction of a degree, ``docs/shape.md``). A stated sex skips the
comparison (probability 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import torch

from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import MEASUREMENT_NAMES, BodyMeasurer


@dataclass(frozen=True)
class SexShapes:
    """The shape part of a posterior with sex as a latent.

    Attributes:
        probabilities: ``{"female": p, "male": 1 - p}``.
        means: per sex, ``(K,)`` the shape posterior's mean.
        covariances: per sex, ``(K, K)`` its full covariance.
        stated: the sex was stated by the user (its probability is 1 by fiat, not measured).
        log_evidence: per sex, the fit's Laplace log evidence (NaN for a sex not fitted).
    """

    probabilities: Mapping[str, float]
    means: Mapping[str, torch.Tensor]
    covariances: Mapping[str, torch.Tensor]
    stated: bool = False
    log_evidence: Mapping[str, float] | None = None

    def __repr__(self) -> str:
        """One line: each sex's probability, whether it was stated, the coefficients' count
        (never the means and covariances: the default repr was 2.6 kB)."""
        shown = ", ".join(f"{sex}={float(p):.3f}" for sex, p in self.probabilities.items())
        sizes = {tuple(mean.shape) for mean in self.means.values()}
        text = f"SexShapes({shown}, stated={self.stated}, means {', '.join(map(str, sizes))})"
        return text if len(text) <= 200 else text[:198] + "…)"

    @property
    def most_probable(self) -> str:
        """The sex with the larger probability (female on a tie)."""
        return max(SEX_NAMES, key=lambda sex: (self.probabilities[sex], sex == "female"))

    def scaled(self, factor: float) -> SexShapes:
        """Every covariance scaled by ``factor²`` (shape std times ``factor``)."""
        covariances = {sex: cov * factor**2 for sex, cov in self.covariances.items()}
        return SexShapes(
            self.probabilities, self.means, covariances, self.stated, self.log_evidence
        )

    def sample_betas(self, noise: torch.Tensor, uniform: torch.Tensor) -> torch.Tensor:
        """``(n, K)`` shapes from the mixture, from standard normal ``noise (n, K)`` and
        ``uniform (n,)`` in [0, 1) that picks each sample's sex."""
        female = uniform < self.probabilities["female"]
        betas = torch.empty_like(noise)
        for sex, chosen in (("female", female), ("male", ~female)):
            if sex not in self.means:
                continue
            lower = torch.linalg.cholesky(self.covariances[sex].to(noise))
            draws = self.means[sex].to(noise) + noise @ lower.T
            betas = torch.where(chosen[:, None], draws, betas)
        return betas

    def log_prob(self, betas: torch.Tensor) -> torch.Tensor:
        """``(N,)`` float64 log density of ``betas (N, K)`` under the mixture
        ``Σ_s p_s N(β; μ_s, Σ_s)`` (Lebesgue measure on β; nats)."""
        terms = []
        for sex, probability in self.probabilities.items():
            if probability <= 0 or sex not in self.means:
                continue
            gaussian = torch.distributions.MultivariateNormal(
                self.means[sex].double().to(betas.device),
                covariance_matrix=self.covariances[sex].double().to(betas.device),
            )
            terms.append(math.log(probability) + gaussian.log_prob(betas.double()))
        return torch.logsumexp(torch.stack(terms), dim=0)

    def measurements(self, measurer: BodyMeasurer) -> dict[str, tuple[float, float]]:
        """``{name: (mean, std)}`` of the six measurements under the mixture, each sex's
        linearised at its mean, combined by the law of total variance."""
        first = torch.zeros(len(MEASUREMENT_NAMES), dtype=torch.float64)
        second = torch.zeros_like(first)
        for sex, probability in self.probabilities.items():
            if probability <= 0 or sex not in self.means:
                continue
            mean, std = measurer.gaussian(self.means[sex], self.covariances[sex])
            first += probability * mean
            second += probability * (std**2 + mean**2)
        std = (second - first**2).clamp_min(0.0).sqrt()
        return {name: (float(first[i]), float(std[i])) for i, name in enumerate(MEASUREMENT_NAMES)}


def sex_probabilities(log_evidence: Mapping[str, float]) -> dict[str, float]:
    """``{"female": p, "male": 1 - p}`` from each sex's log evidence, the sexes equally likely
    a priori; a sex whose evidence is not finite gets 0 (both: ½ each)."""
    finite = {sex: value for sex, value in log_evidence.items() if math.isfinite(value)}
    if not finite:
        return dict.fromkeys(SEX_NAMES, 0.5)
    top = max(finite.values())
    weights = {sex: math.exp(finite[sex] - top) if sex in finite else 0.0 for sex in SEX_NAMES}
    total = sum(weights.values())
    female = weights["female"] / total
    return {"female": female, "male": 1.0 - female}


def gaussian_measurements(
    measurer: BodyMeasurer, mean: torch.Tensor, std: torch.Tensor
) -> dict[str, tuple[float, float]]:
    """``{name: (mean, std)}`` for a diagonal shape Gaussian (a posterior without sexes)."""
    means, stds = measurer.gaussian(mean, torch.diag(std.double().cpu() ** 2))
    return {name: (float(means[i]), float(stds[i])) for i, name in enumerate(MEASUREMENT_NAMES)}

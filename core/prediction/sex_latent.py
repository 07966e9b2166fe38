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

The face is a second, independent kind of evidence (:mod:`hkpd.prediction.detection.face_sex`):
its calibrated P(male) enters as a likelihood ratio, its log-odds added to the fits' (both read
with the sexes equally likely a priori). :class:`SexEvidence` keeps each source's word apart.
When neither sex is probable enough (:data:`SURE_SEX_PROBABILITY`), or the reading itself is in
doubt, the body drawn claims neither sex: the mode's shape is the two sexes' fitted shapes'
midpoint (:meth:`SexShapes.drawn_mean`), a build both fits share, with neither sex's chest and
hips.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import torch

from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import MEASUREMENT_NAMES, BodyMeasurer

SURE_SEX_PROBABILITY = 0.8
"""Below this probability of the more probable sex the body drawn is neither sex's (the
evidence is then no better than one wrong call in five; docs/shape.md, "The face")."""

FACE_PROBABILITY_LIMIT = 1e-3
"""The face's P(male) is clipped to [limit, 1 - limit]: no one face decides beyond 1000:1."""

NEUTRAL = "neutral"
""":attr:`SexShapes.drawn`'s name for the body that claims neither sex."""


@dataclass(frozen=True)
class FaceWord:
    """What the face said of the sex: ``p_male`` (calibrated, in (0, 1)) or None with the
    ``reason`` it said nothing, in words (None reason: the face was not read); the face's
    apparent ``age_years`` (None: unknown) and whether that is a ``child``'s."""

    p_male: float | None = None
    reason: str | None = None
    age_years: float | None = None
    child: bool = False


@dataclass(frozen=True)
class SexEvidence:
    """Where the sex's probability came from, each source on its own.

    Attributes:
        keypoints: P(male) from the keypoint fits' Laplace evidence alone (the body's
            proportions; sexes equally likely a priori).
        face: P(male) the face says, calibrated (:mod:`hkpd.prediction.detection.face_sex`),
            or None when the face said nothing.
        face_reason: why the face said nothing (e.g. ``"no face: seen from behind"``), or
            None when it spoke or was not read.
    """

    keypoints: float
    face: float | None = None
    face_reason: str | None = None

    def as_dict(self) -> dict[str, float | None]:
        """``{"face": p_male or None, "keypoints": p_male}`` (summary.json's ``sex_evidence``)."""
        return {"face": self.face, "keypoints": self.keypoints}

    @property
    def source(self) -> str:
        """``"face"`` when the face spoke, else ``"keypoints"``."""
        return "keypoints" if self.face is None else "face"


@dataclass(frozen=True)
class SexShapes:
    """The shape part of a posterior with sex as a latent.

    Attributes:
        probabilities: ``{"female": p, "male": 1 - p}``.
        means: per sex, ``(K,)`` the shape posterior's mean.
        covariances: per sex, ``(K, K)`` its full covariance.
        stated: the sex was stated by the user (its probability is 1 by fiat, not measured).
        log_evidence: per sex, the fit's Laplace log evidence (NaN for a sex not fitted).
        evidence: each source's word on the sex (None: stated, or combined photos).
        doubted: the reading itself is in doubt (its quality score warns), so no sex is
            claimed whatever the probabilities say.
    """

    probabilities: Mapping[str, float]
    means: Mapping[str, torch.Tensor]
    covariances: Mapping[str, torch.Tensor]
    stated: bool = False
    log_evidence: Mapping[str, float] | None = None
    evidence: SexEvidence | None = None
    doubted: bool = False

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

    @property
    def sure(self) -> bool:
        """The body may claim a sex: it was stated, or the more probable sex has at least
        :data:`SURE_SEX_PROBABILITY` and the reading is not in doubt."""
        if self.stated:
            return True
        return not self.doubted and self.probabilities[self.most_probable] >= SURE_SEX_PROBABILITY

    @property
    def drawn(self) -> str:
        """The sex of the body drawn: :attr:`most_probable` when :attr:`sure`, else
        :data:`NEUTRAL`."""
        return self.most_probable if self.sure or len(self.means) < 2 else NEUTRAL

    def drawn_mean(self) -> torch.Tensor:
        """``(K,)`` the drawn body's shape: the more probable sex's mean, or, for
        :data:`NEUTRAL`, the midpoint of the two sexes' means (each fitted to the same
        photo, so the build they share, halfway between the sexes' chests and hips)."""
        if self.drawn != NEUTRAL:
            return self.means[self.most_probable]
        return 0.5 * (self.means["female"] + self.means["male"].to(self.means["female"]))

    def with_doubt(self, doubted: bool = True) -> SexShapes:
        """This record with :attr:`doubted` set."""
        return replace(self, doubted=doubted)

    def scaled(self, factor: float) -> SexShapes:
        """Every covariance scaled by ``factor²`` (shape std times ``factor``)."""
        covariances = {sex: cov * factor**2 for sex, cov in self.covariances.items()}
        return replace(self, covariances=covariances)

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


def face_log_odds(face_p_male: float | None) -> float:
    """log(P(male) / P(female)) of the face's word, clipped to
    :data:`FACE_PROBABILITY_LIMIT`; 0 when the face said nothing."""
    if face_p_male is None or not math.isfinite(face_p_male):
        return 0.0
    p = min(max(float(face_p_male), FACE_PROBABILITY_LIMIT), 1.0 - FACE_PROBABILITY_LIMIT)
    return math.log(p / (1.0 - p))


def sex_probabilities(
    log_evidence: Mapping[str, float], face_p_male: float | None = None
) -> dict[str, float]:
    """``{"female": p, "male": 1 - p}`` from each sex's log evidence and the face's calibrated
    P(male) (None: no face), the sexes equally likely a priori; a sex whose evidence is not
    finite gets 0 (both: ½ each, before the face)."""
    finite = {sex: value for sex, value in log_evidence.items() if math.isfinite(value)}
    if finite and "male" in finite:
        finite["male"] += face_log_odds(face_p_male)
    elif not finite:
        male = 1.0 / (1.0 + math.exp(-face_log_odds(face_p_male)))
        return {"female": 1.0 - male, "male": male}
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

"""Several photos of one person with sex as a latent: one combined shape per sex, one sex.

Each photo's posterior holds, per sex, a full-covariance shape Gaussian and a probability
(:class:`hkpd.prediction.sex_latent.SexShapes`). For independent photos of one body:

- per sex, the shape given every photo is the product of the photos' Gaussians (precisions
  add), as :mod:`hkpd.prediction.shape_combination` does for one Gaussian per photo;
- the sexes' log-odds add (equal prior odds);
- a stated measurement entered every photo's posterior and every photo's sex evidence, so its
  information is taken out ``N - 1`` times (linearised at the combined mean, re-linearised
  three times) and its log-odds ``N - 1`` times: it counts once, as stated.

A stated sex stays stated. Photos without sexes (body models without sex priors, the network's
own posterior) cannot be combined this way: :func:`combine_sexes` returns None for them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import torch

from hkpd.body import BodyModel
from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import MEASUREMENT_NAMES, body_measurer
from hkpd.conditioning import StatedBody, conditioned_on_measurements
from hkpd.conditioning.shape_prior import RELINEARISATIONS, ShapeGaussian
from hkpd.prediction.sex_latent import SexShapes, sex_probabilities


class SexedShape(Protocol):
    """What :func:`combine_sexes` reads of a photo: a :class:`BodyPosterior`, or any record
    with the posterior's ``sexes`` and ``stated``."""

    sexes: SexShapes | None
    stated: StatedBody | None


def combine_sexes(posteriors: Sequence[SexedShape], body: BodyModel) -> SexShapes | None:
    """The combined :class:`SexShapes` of ``N >= 1`` photos of one person (module docstring),
    or None when a photo has no sexes.

    Raises:
        ValueError: the photos were given different stated values.
    """
    if not posteriors or any(posterior.sexes is None for posterior in posteriors):
        return None
    stated = _common_stated(posteriors)
    shapes = [posterior.sexes for posterior in posteriors]
    extra = len(posteriors) - 1
    means, covariances = {}, {}
    for sex in SEX_NAMES:
        if not all(sex in item.means for item in shapes):
            continue
        precision = sum(torch.linalg.inv(item.covariances[sex].double()) for item in shapes)
        information = sum(
            torch.linalg.solve(item.covariances[sex].double(), item.means[sex].double())
            for item in shapes
        )
        mean, covariance = _counted_once(precision, information, stated, body, extra)
        means[sex], covariances[sex] = mean.float(), covariance.float()
    if stated.sex is not None:
        probabilities = {sex: float(sex == stated.sex) for sex in SEX_NAMES}
    else:
        log_odds = dict.fromkeys(SEX_NAMES, 0.0)
        for item in shapes:
            for sex in SEX_NAMES:
                log_odds[sex] += math.log(max(item.probabilities[sex], 1e-300))
        for sex, value in _stated_log_evidence(stated, body).items():
            log_odds[sex] -= extra * value
        probabilities = sex_probabilities(log_odds)
    return SexShapes(probabilities, means, covariances, stated.sex is not None)


def _common_stated(posteriors: Sequence[SexedShape]) -> StatedBody:
    """What every photo was given (the same for all), or a ValueError."""
    stated = [posterior.stated or StatedBody() for posterior in posteriors]
    first = stated[0]
    if any(item != first for item in stated[1:]):
        raise ValueError(
            "the photos were given different stated values (sex, measurements); state the same "
            "for every photo of one person"
        )
    return first


def _counted_once(
    precision: torch.Tensor,
    information: torch.Tensor,
    stated: StatedBody,
    body: BodyModel,
    extra: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(mean (K,), covariance (K, K))`` of the product, with ``extra`` copies of the stated
    measurements' (linearised) information taken out."""
    covariance = torch.linalg.inv(precision)
    mean = covariance @ information
    if not stated.measurements or extra == 0:
        return mean, 0.5 * (covariance + covariance.T)
    measurer = body_measurer(body)
    columns = [MEASUREMENT_NAMES.index(name) for name in stated.measurements]
    values = torch.tensor([value for value, _ in stated.measurements.values()], dtype=torch.float64)
    weights = torch.tensor([std for _, std in stated.measurements.values()]).double() ** -2
    for _ in range(RELINEARISATIONS):
        jacobian = measurer.jacobian(mean)[columns]  # (M, K)
        offset = values - measurer(mean[None])[0, columns] + jacobian @ mean
        corrected = precision - extra * jacobian.T @ (weights[:, None] * jacobian)
        corrected_information = information - extra * jacobian.T @ (weights * offset)
        covariance = torch.linalg.inv(corrected)
        mean = covariance @ corrected_information
    return mean, 0.5 * (covariance + covariance.T)


def _stated_log_evidence(stated: StatedBody, body: BodyModel) -> dict[str, float]:
    """Per sex, the log evidence of the stated measurements alone under that sex's population
    (what each photo's sex evidence holds of them); zeros when none are stated."""
    if not stated.measurements:
        return dict.fromkeys(SEX_NAMES, 0.0)
    evidence = {}
    for sex in SEX_NAMES:
        mean, covariance = body.sex_shape_prior(sex)
        population = ShapeGaussian(
            mean.double()[None], covariance.double()[None], torch.zeros(1, dtype=torch.float64)
        )
        updated = conditioned_on_measurements(population, body_measurer(body), stated.measurements)
        evidence[sex] = float(updated.log_weight[0])
    return evidence

"""The combined shape of ``hkpd-predict --same-person``, from what each photo's run kept.

A run over many photos keeps of each posterior only its shape (:class:`PhotoShape`: the
diagonal Gaussian, the per-sex shapes and probabilities, what was stated), not the posterior
with its photo and proxies. :func:`combine_photo_shapes` then combines them as
:func:`hkpd.prediction.shape_combination.combine_shapes` combines posteriors: with sex as a
latent, per sex the product of the photos' full-covariance Gaussians, the sexes' log-odds
added and a stated measurement counted once (:mod:`hkpd.prediction.sex_combination`);
otherwise the product of the diagonal Gaussians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import torch

from hkpd.body import BodyModel
from hkpd.body.measurements import body_measurer
from hkpd.prediction.sex_combination import combine_sexes
from hkpd.prediction.sex_latent import SexShapes, gaussian_measurements
from hkpd.prediction.shape_combination import (
    CombinationMethod,
    CombinedShape,
    combine_shape_tensors,
    stack_shape_distributions,
)

if TYPE_CHECKING:
    from hkpd.conditioning import StatedBody
    from hkpd.prediction.posterior import BodyPosterior


@dataclass(frozen=True)
class PhotoShape:
    """The shape part of one photo's posterior.

    Attributes:
        shape_mean: ``(K,)`` the posterior's (the drawn sex's) shape mean, CPU.
        shape_std: ``(K,)`` its standard deviations.
        sexes: per sex the full-covariance shape and the probability, or None (the network's
            own posterior, a body model without sex priors).
        stated: what the photo was given (sex, measurements), or None.
    """

    shape_mean: torch.Tensor
    shape_std: torch.Tensor
    sexes: SexShapes | None = None
    stated: StatedBody | None = None

    @classmethod
    def of(cls, posterior: BodyPosterior) -> PhotoShape:
        """The shape part of ``posterior`` (tensors detached, on the CPU)."""
        return cls(
            posterior.shape_mean.detach().cpu(),
            posterior.shape_std.detach().cpu(),
            posterior.sexes,
            posterior.stated,
        )

    @property
    def sex_probabilities(self) -> dict[str, float] | None:
        """``{"female": p, "male": 1 - p}`` or None without sexes."""
        return None if self.sexes is None else dict(self.sexes.probabilities)


def combine_photo_shapes(
    photos: Sequence[PhotoShape], body: BodyModel, method: CombinationMethod = "product"
) -> CombinedShape:
    """The shape of one person from ``N >= 1`` photos' shapes.

    With ``"product"`` and sexes in every photo: per sex as
    :func:`hkpd.prediction.sex_combination.combine_sexes` (``CombinedShape.sexes``; its
    ``betas_mean``/``betas_std`` are the more probable sex's); otherwise (``"mean"``, or a
    photo without sexes) :func:`combine_shape_tensors` of the diagonal Gaussians.

    Raises:
        ValueError: as :func:`combine_shape_tensors`, or photos given different stated values.
    """
    means, stds = stack_shape_distributions(photos)
    if method != "product" or any(photo.sexes is None for photo in photos):
        return combine_shape_tensors(means, stds, body, method)
    # combine_sexes reads only each item's .sexes and .stated, which a PhotoShape has.
    sexes = combine_sexes(photos, body)  # type: ignore[arg-type]
    if sexes is None:
        return combine_shape_tensors(means, stds, body, method)
    sex = sexes.most_probable
    mean = sexes.means[sex].to(means.dtype)
    std = sexes.covariances[sex].diagonal().clamp_min(0).sqrt().to(stds.dtype)
    combined = combine_shape_tensors(mean[None], std[None], body, method)
    return replace(combined, count=len(photos), sexes=sexes)


def combined_measurements(
    combined: CombinedShape, body: BodyModel
) -> dict[str, tuple[float, float]]:
    """``{name: (mean, std)}`` of the combined shape (metres, kilograms): over both sexes by
    their combined probabilities when it has sexes, else of its diagonal Gaussian."""
    measurer = body_measurer(body)
    if combined.sexes is not None:
        return combined.sexes.measurements(measurer)
    return gaussian_measurements(measurer, combined.betas_mean, combined.betas_std)

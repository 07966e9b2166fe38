"""The shape combined from the current photo and the added photos of the same person.

With sex as a latent (every photo's posterior has ``sexes``) the photos combine per sex, the
sexes' log-odds added and a stated value counted once
(:func:`hkpd.prediction.combine_shapes`, :mod:`hkpd.prediction.sex_combination`); otherwise
(photos without sexes, or predicted with different stated values because the Body section
changed after a photo was added) by the product of their diagonal shape Gaussians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from hkpd.explorer.state import SamePersonShape
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.shape_combination import CombinedShape, combine_shape_tensors, combine_shapes


@dataclass(frozen=True)
class _AddedPhoto:
    """An added photo's shape as :func:`combine_shapes` reads a posterior's."""

    shape_mean: torch.Tensor
    shape_std: torch.Tensor
    sexes: object
    stated: object

    @classmethod
    def of(cls, shape: SamePersonShape) -> _AddedPhoto:
        mean = torch.tensor(shape.mean, dtype=torch.float64)
        return cls(mean, torch.tensor(shape.std, dtype=torch.float64), shape.sexes, shape.stated)


def combined_photos(posterior: BodyPosterior, added: Sequence[SamePersonShape]) -> CombinedShape:
    """The current photo's ``posterior`` combined with the ``added`` photos' shapes.

    Raises:
        ValueError: the photos' shape coefficients do not fit together.
    """
    photos = [_AddedPhoto.of(shape) for shape in added]
    stated = [posterior.stated, *(photo.stated for photo in photos)]
    if (
        posterior.sexes is not None
        and all(photo.sexes is not None for photo in photos)
        and all(item == stated[0] for item in stated)
    ):
        return combine_shapes([posterior, *photos], posterior.body)  # type: ignore[list-item]
    means = torch.stack([posterior.shape_mean.detach().cpu().double()]
                        + [photo.shape_mean for photo in photos])  # fmt: skip
    stds = torch.stack([posterior.shape_std.detach().cpu().double()]
                       + [photo.shape_std for photo in photos])  # fmt: skip
    return combine_shape_tensors(means, stds, posterior.body)

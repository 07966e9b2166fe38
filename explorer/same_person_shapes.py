"""The shape combined from the current photo and the added photos of the same person.

With sex as a latent (every photo's posterior has ``sexes``) the photos combine per sex, the
sexes' log-odds added and a stated value counted once
(:func:`hkpd.prediction.combine_shapes`, :mod:`hkpd.prediction.sex_combination`); otherwise
(photos without sexes, or predicted with different stated values because the Body section
changed after a photo was added) by the product of their diagonal shape Gaussians.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from hkpd.explorer.state import SamePersonShape
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.shape_combination import CombinedShape, combine_shape_tensors, combine_shapes


def combined_photos(posterior: BodyPosterior, added: Sequence[SamePersonShape]) -> CombinedShape:
    """The current photo's ``posterior`` combined with the ``added`` photos' shapes.

    Raises:
        ValueError: the photos' shape coefficients do not fit together.
    """
    stated = [posterior.stated, *(shape.stated for shape in added)]
    if (
        posterior.sexes is not None
        and all(shape.sexes is not None for shape in added)
        and all(item == stated[0] for item in stated)
    ):
        return combine_shapes([posterior, *added], posterior.body)  # type: ignore[list-item]
    means = torch.stack([posterior.shape_mean.detach().cpu().double()]
                        + [shape.shape_mean for shape in added])  # fmt: skip
    stds = torch.stack([posterior.shape_std.detach().cpu().double()]
                       + [shape.shape_std for shape in added])  # fmt: skip
    return combine_shape_tensors(means, stds, posterior.body)

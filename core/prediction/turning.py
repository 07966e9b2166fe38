"""The turned-around reading of a photo: the same keypoints fitted by a body facing the other way.

Under the weak-perspective camera a body and its depth-mirrored twin project to the same
points: reflect the camera frame's depth (``D = diag(1, 1, -1)``) and the body's left and right
(``M = diag(-1, 1, 1)`` in body axes, left and right joints swapped). The twin's global rotation
is ``D R_g M`` (a rotation: two reflections), its relative rotations ``M R M`` with left and
right swapped, and it faces the other way; what BlazePose called its left is now its right. A
person seen from behind whom the detector labelled as facing the camera is therefore read right
by fitting the left/right-swapped keypoints from the turned body. BlazePose's face-based
detector does this to most people seen from behind (``docs/evidence.md``); nothing in one photo
says which reading is true when the face is hidden, so the user chooses
(:meth:`hkpd.prediction.BodyPosterior.turned_around`, the explorer's *Turn around*,
``hkpd-predict --turn-around``).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import torch

from hkpd.coco_keypoints import COCO17_MIRROR_ORDER
from hkpd.conditioning import KeypointEvidence, condition_on_keypoints
from hkpd.distributions import BodyDistribution
from hkpd.mirror_symmetry import BODY_MIRROR_PERMUTATION, reflect_rotations
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.second_evidence import combined_keypoint_evidence
from hkpd.prediction.sex_fits import fit_each_sex, with_drawn_body

if TYPE_CHECKING:
    from hkpd.prediction.predictor import Predictor

DEPTH_FLIP = torch.tensor([1.0, 1.0, -1.0])
"""``D``'s diagonal: the camera frame's depth reflected."""


def turned_distribution(distribution: BodyDistribution) -> BodyDistribution:
    """The depth-mirrored, left/right-swapped twin of ``distribution`` (any batch shape):
    ``F`` mirrored joint by joint (left and right swapped), ``global_orient`` ``D R_g M``;
    shape and camera unchanged. Its own inverse."""
    permutation = torch.tensor(BODY_MIRROR_PERMUTATION, device=distribution.F.device)
    depth = DEPTH_FLIP.to(distribution.global_orient)
    mirror = torch.tensor([-1.0, 1.0, 1.0]).to(distribution.global_orient)
    orient = depth[:, None] * distribution.global_orient * mirror[None, :]
    return replace(
        distribution,
        F=reflect_rotations(distribution.F[..., permutation, :, :]),
        global_orient=orient,
    )


def swapped_evidence(evidence: KeypointEvidence) -> KeypointEvidence:
    """``evidence`` with left and right keypoints' labels swapped (positions unchanged)."""
    order = list(COCO17_MIRROR_ORDER)
    return KeypointEvidence(evidence.keypoints[order], evidence.observed[order], evidence.crop_size)


def turn_around(predictor: Predictor, posterior: BodyPosterior) -> BodyPosterior:
    """The turned-around evidence posterior of ``posterior`` (module docstring): the keypoints
    with left and right swapped, fitted from the turned network reading, under each sex's
    prior and the stated values as the original was (the person mask and the hand and foot
    landmarks are not refitted). How probable each sex is belongs to the photo (its face and
    keypoints as first read), so turning keeps it; only the shapes are refitted. Its
    :meth:`~BodyPosterior.turned_around` gives ``posterior`` back.

    Raises:
        ValueError: ``posterior`` is not an evidence posterior of a photo.
    """
    prepared, reading = posterior.network_input, posterior.prior
    if prepared is None or reading is None or not posterior.conditioned:
        raise ValueError(
            "only an evidence posterior of a photo can be turned around (it refits the "
            "photo's keypoints); predict with evidence=True"
        )
    keypoints_crop, observed = combined_keypoint_evidence(prepared)
    evidence = swapped_evidence(
        KeypointEvidence(
            torch.as_tensor(keypoints_crop, dtype=torch.float64),
            torch.as_tensor(observed),
            predictor.crop_size,
        )
    )
    start = turned_distribution(reading.distribution).map(lambda t: t[None].float().cpu())
    config = replace(predictor.evidence_config, facings=1)  # the turn is the point: keep it
    body64 = predictor.float64_body_model()
    sexes = None
    if posterior.sexes is not None and posterior.stated is not None:
        fits = fit_each_sex(body64, start, evidence, config, (), posterior.stated,
                            face=posterior.face, decided=posterior.sexes)  # fmt: skip
        fit, sexes = fits.winner, fits.shapes
    else:
        fit = condition_on_keypoints(body64, start, evidence, config)
    if fit.conditioned is None:
        raise ValueError(f"the turned-around fit failed: {fit.reason}")
    turned_prior = replace(reading, distribution=turned_distribution(reading.distribution))
    turned = replace(
        posterior,
        distribution=fit.conditioned.map(lambda t: t.float().to(posterior.F.device)),
        prior=turned_prior,
        evidence_fit=fit,
        sexes=sexes,
        turned=not posterior.turned,
        turner=lambda _: posterior,
    )
    return with_drawn_body(turned)

"""One keypoint fit per sex, and the posterior's shape with sex as a latent.

:func:`fit_each_sex` re-bases the network's shape reading on each sex's population prior
(:func:`hkpd.conditioning.rebased_on_population`), conditions it on the stated measurements
(:func:`hkpd.conditioning.conditioned_on_measurements`), fits the evidence under it, and turns
the fits' Laplace evidence into the sexes' probabilities (:mod:`hkpd.prediction.sex_latent`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from hkpd.body import BodyModel
from hkpd.body.asset import SEX_NAMES
from hkpd.body.measurements import body_measurer
from hkpd.conditioning import (
    EvidenceConfig,
    EvidenceTerm,
    KeypointEvidence,
    KeypointFit,
    ShapeGaussian,
    StatedBody,
    condition_on_keypoints,
    conditioned_on_measurements,
    rebased_on_population,
)
from hkpd.distributions import BodyDistribution
from hkpd.prediction.posterior import BodyPosterior
from hkpd.prediction.quality import ReadingQuality
from hkpd.prediction.sex_latent import (
    NEUTRAL,
    FaceWord,
    SexEvidence,
    SexShapes,
    sex_probabilities,
)

__all__ = [
    "FACE_DOUBT_FLAGS",
    "FaceWord",
    "SexFits",
    "doubts_the_sex",
    "fit_each_sex",
    "sex_shape_priors",
    "with_drawn_body",
    "with_drawn_shape",
    "with_sex_shape",
]


@dataclass(frozen=True)
class SexFits:
    """The fits of one photo under each sex's prior.

    Attributes:
        fits: per fitted sex, its keypoint fit.
        priors: per fitted sex, the shape prior the fit used (``B`` rows, one per start).
        shapes: the posterior's shape with sex as a latent.
    """

    fits: dict[str, KeypointFit]
    priors: dict[str, ShapeGaussian]
    shapes: SexShapes

    @property
    def winner(self) -> KeypointFit:
        """The more probable sex's fit: the posterior's pose and drawn body."""
        return self.fits[self.shapes.most_probable]


def sex_shape_priors(
    body: BodyModel,
    starts: BodyDistribution,
    config: EvidenceConfig,
    stated: StatedBody,
) -> dict[str, ShapeGaussian]:
    """Per sex to fit (the stated one, or both), the fit's shape prior for the ``B`` starts."""
    sexes = SEX_NAMES if stated.sex is None else (stated.sex,)
    priors = {}
    for sex in sexes:
        mean, covariance = body.sex_shape_prior(sex)
        prior = rebased_on_population(
            starts.shape_mean, starts.shape_std, mean, covariance, config.prior_weight
        )
        priors[sex] = conditioned_on_measurements(prior, body_measurer(body), stated.measurements)
    return priors


def fit_each_sex(
    body64: BodyModel,
    starts: BodyDistribution,
    evidence: KeypointEvidence,
    config: EvidenceConfig,
    extra_terms: Sequence[EvidenceTerm],
    stated: StatedBody,
    face: FaceWord | None = None,
    decided: SexShapes | None = None,
) -> SexFits:
    """Fit ``evidence`` from the ``B`` starts under each sex's shape prior.

    Args:
        body64: float64 body model with sex priors.
        starts: the network's ``B`` readings (the starts and their pose priors).
        evidence: the keypoints.
        config: the evidence settings.
        extra_terms: further evidence (the person mask).
        stated: what the user stated (a stated sex is the only one fitted).
        face: what the face said of the sex (its calibrated P(male), or why it said nothing),
            evidence beside the fits' (:func:`sex_probabilities`); None: not read.
        decided: the sexes as already read on the photo without occluders
            (:class:`hkpd.prediction.photo_reading.PhotoReading`): their probabilities and what
            each source said are kept (a box removes evidence, it does not change how the photo
            is read); only the shapes are fitted again. None: weighed by these fits.

    Returns:
        :class:`SexFits`. A fit that fails keeps its prior's shape (first start) and weight.
    """
    priors = sex_shape_priors(body64, starts, config, stated)
    fits, means, covariances, log_evidence = {}, {}, {}, {}
    for sex, prior in priors.items():
        fit = condition_on_keypoints(
            body64, starts, evidence, config, extra_terms=extra_terms, shape_prior=prior
        )
        fits[sex] = fit
        if fit.conditioned is not None and fit.shape_covariance is not None:
            means[sex] = fit.conditioned.shape_mean.float()
            covariances[sex] = fit.shape_covariance.float()
            log_evidence[sex] = fit.log_evidence
        else:
            means[sex], covariances[sex] = prior.mean[0].float(), prior.covariance[0].float()
            log_evidence[sex] = float(prior.log_weight[0])
    evidence = None
    if stated.sex is not None:
        probabilities = {sex: float(sex == stated.sex) for sex in SEX_NAMES}
    elif decided is not None:
        probabilities, evidence = dict(decided.probabilities), decided.evidence
    else:
        face = face or FaceWord()
        probabilities = sex_probabilities(log_evidence, face.p_male)
        keypoints = sex_probabilities(log_evidence)["male"]
        evidence = SexEvidence(keypoints, face.p_male, face.reason)
    shapes = SexShapes(
        probabilities,
        means,
        covariances,
        stated.sex is not None,
        dict(log_evidence),
        evidence=evidence,
    )
    return SexFits(fits, priors, shapes)


def with_drawn_shape(posterior: BodyPosterior) -> BodyPosterior:
    """``posterior`` drawing the body its sexes say (:attr:`SexShapes.drawn`): unchanged when
    that is the more probable sex, the two sexes' midpoint shape when it is neither."""
    sexes = posterior.sexes
    if sexes is None or sexes.drawn != NEUTRAL:
        return posterior
    return with_sex_shape(posterior, sexes)


def with_sex_shape(posterior: BodyPosterior, shapes: SexShapes) -> BodyPosterior:
    """``posterior`` with ``shapes`` as its sexes and the drawn body's shape
    (:meth:`SexShapes.drawn_mean`: the more probable sex's, or neither sex's when unsure) as its
    shape Gaussian's mean (the std is the more probable sex's)."""
    sex = shapes.most_probable
    mean = shapes.drawn_mean().to(posterior.shape_mean)
    std = shapes.covariances[sex].diagonal().clamp_min(0.0).sqrt().to(posterior.shape_std)
    distribution = replace(posterior.distribution, shape_mean=mean, shape_std=std)
    edited = replace(posterior, distribution=distribution, sexes=shapes)
    if "pose_distribution" in posterior.__dict__:
        edited.__dict__["pose_distribution"] = posterior.pose_distribution
    return edited


FACE_DOUBT_FLAGS = frozenset({"off_centre_in_box"})
"""Warnings that doubt a face-read sex too: the person read may be someone beside the one asked
for, and so may their face. Other warnings (keypoints cut off, readers that disagree on a limb)
doubt the pose, not whose face was read: on coco_mini val2017 every face-read sex doubted by
them alone was right (7 of 7; docs/shape.md section 7)."""


def doubts_the_sex(sexes: SexShapes, quality: ReadingQuality) -> bool:
    """Whether a sure, unstated sex is in doubt on a reading of this quality: the reading is
    warned about (:attr:`ReadingQuality.low`) and either the face said nothing (the sex is the
    keypoints' alone) or a warning says the person read may be someone else
    (:data:`FACE_DOUBT_FLAGS`)."""
    if sexes.stated or not quality.low:
        return False
    face_spoke = sexes.evidence is not None and sexes.evidence.face is not None
    return not face_spoke or bool(FACE_DOUBT_FLAGS.intersection(quality.flags))


def with_drawn_body(posterior: BodyPosterior) -> BodyPosterior:
    """``posterior`` drawing the body it may claim: a sure sex that the reading's quality puts
    in doubt (:func:`doubts_the_sex`) is doubted, and a sex that is not sure (or doubted) draws
    neither sex's build (:func:`with_drawn_shape`). A stated sex is drawn as stated."""
    sexes = posterior.sexes
    if sexes is None or sexes.stated:
        return posterior
    if sexes.sure and doubts_the_sex(sexes, posterior.quality):
        posterior = replace(posterior, sexes=sexes.with_doubt())
    return with_drawn_shape(posterior)

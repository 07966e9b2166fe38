"""Shape read on the synthetic test set: the network's and the evidence posterior's shape
Gaussians scored against the true coefficients (:mod:`hkpd.evaluation.shape_metrics`).

Each test example (the fixed test set of :mod:`hkpd.evaluation.test_set`, rendered again here
with the same seeds so that its silhouette is at hand) gets detector-like keypoints
(:func:`hkpd.synthesis.detector_noise.detector_like_keypoints`, the same draws as the
``--evidence`` rows) and a detector-like mask: its exact silhouette in crop pixels (the body's
rendered pixels), unknown where the occlusion augmentations hid it, degraded by
:func:`hkpd.synthesis.mask_noise.detector_like_masks`. The evidence posterior weighs the
keypoints and whatever terms ``extra_terms_for(example)`` makes of the mask (none by default:
keypoints only), so a silhouette term is plugged in without changing this module.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import torch

from hkpd.body import BodyModel
from hkpd.conditioning import (
    EvidenceConfig,
    EvidenceTerm,
    SilhouetteConfig,
    SilhouetteEvidence,
    SilhouetteTerm,
    SurfaceSamples,
)
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.evidence_synthetic import condition_batch
from hkpd.evaluation.shape_metrics import ShapeScores, shape_scores
from hkpd.evaluation.test_set import (
    TEST_BATCH_SIZE,
    TEST_SET_SEED,
    network_and_generator,
    stored_evidence_settings,
)
from hkpd.prediction.predictor import float64_body
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints
from hkpd.synthesis.generator import RenderedBatch, SyntheticDataGenerator, batch_seed
from hkpd.synthesis.mask_noise import MaskNoise, detector_like_masks

MASK_SEED_OFFSET = 1
"""The masks' noise is seeded with ``seed + MASK_SEED_OFFSET`` (the keypoints' with ``seed``, as
in :func:`hkpd.evaluation.evidence_synthetic.evaluate_evidence_batches`)."""

NETWORK_POSTERIOR = "network"
"""The name of the network's own posterior in :func:`read_posteriors` (and the scores)."""


@dataclass(frozen=True)
class MaskedExample:
    """What the photo's mask says about one synthetic example, in its crop.

    Attributes:
        probability: ``(S, S)`` float32 in [0, 1], the detector-like person mask.
        known: ``(S, S)`` bool, False where the photo says neither body nor background.
        crop_size: ``S``, pixels.
        silhouette: ``(S, S)`` bool, the exact silhouette (for scoring, not evidence).
    """

    probability: torch.Tensor
    known: torch.Tensor
    crop_size: int
    silhouette: torch.Tensor


ExtraTermsFor = Callable[[MaskedExample], list[EvidenceTerm]]
"""Makes the evidence terms beyond the keypoints for one example (e.g. a silhouette term)."""


def no_extra_terms(example: MaskedExample) -> list[EvidenceTerm]:
    """The default :data:`ExtraTermsFor`: keypoints only."""
    return []


def silhouette_terms_for(body: BodyModel, config: SilhouetteConfig | None = None) -> ExtraTermsFor:
    """An :data:`ExtraTermsFor` that conditions on each example's detector-like mask with the
    predictor's :class:`hkpd.conditioning.SilhouetteTerm` (surface samples of ``body``, made
    once)."""
    surface = SurfaceSamples.of(body)

    def terms(example: MaskedExample) -> list[EvidenceTerm]:
        evidence = SilhouetteEvidence(
            example.probability.detach().cpu().double(),
            example.known.detach().cpu().bool(),
            example.crop_size,
        )
        return [SilhouetteTerm(evidence, surface, config)]

    return terms


def rendered_test_set(
    generator: SyntheticDataGenerator, count: int, seed: int = TEST_SET_SEED
) -> Iterator[RenderedBatch]:
    """The batches of :func:`hkpd.evaluation.test_set.fixed_batches` with their pictures (the
    same examples: the same batch sizes and seeds)."""
    for index, start in enumerate(range(0, count, TEST_BATCH_SIZE)):
        size = min(TEST_BATCH_SIZE, count - start)
        yield generator.generate(size, batch_seed(seed, index))


def masked_examples(
    rendered: RenderedBatch, noise: MaskNoise, generator: torch.Generator
) -> list[MaskedExample]:
    """The detector-like mask of every example of ``rendered`` (exact silhouette: the body's
    pixels; unknown: what the occlusion augmentations hid)."""
    silhouettes = rendered.part_map >= 0
    known = ~rendered.occluded
    probability = detector_like_masks(silhouettes & known, known, noise, generator)
    size = int(silhouettes.shape[-1])
    return [
        MaskedExample(probability[i], known[i], size, silhouettes[i])
        for i in range(silhouettes.shape[0])
    ]


@dataclass
class DetectorLikeInputs:
    """How the detector-like keypoints and masks of the examples are drawn, and the random
    streams they are drawn from (one per kind, so adding a posterior changes no draw)."""

    keypoints: DetectorNoise
    masks: MaskNoise
    keypoint_stream: torch.Generator
    mask_stream: torch.Generator

    @classmethod
    def seeded(
        cls,
        seed: int,
        keypoint_noise: DetectorNoise | None = None,
        mask_noise: MaskNoise | None = None,
    ) -> DetectorLikeInputs:
        """The noise models (defaults: their dataclasses') with the keypoints' stream seeded
        by ``seed`` and the masks' by ``seed + MASK_SEED_OFFSET``."""
        return cls(
            keypoint_noise or DetectorNoise(),
            mask_noise or MaskNoise(),
            torch.Generator().manual_seed(seed),
            torch.Generator().manual_seed(seed + MASK_SEED_OFFSET),
        )


def read_posteriors(
    network: torch.nn.Module,
    rendered: RenderedBatch,
    posteriors: Mapping[str, ExtraTermsFor],
    config: EvidenceConfig,
    body64: BodyModel,
    inputs: DetectorLikeInputs | None,
) -> dict[str, BodyDistribution]:
    """Every posterior of one rendered batch: the network's reading (:data:`NETWORK_POSTERIOR`)
    and, with ``inputs``, each evidence posterior of ``posteriors``, fitted to the batch's
    detector-like keypoints and to the terms its ``ExtraTermsFor`` makes of each example's
    detector-like mask (examples whose fit fails keep the network's reading)."""
    batch = rendered.batch
    size = batch.proxy.shape[-1]
    output = network(batch.proxy)
    readings = {NETWORK_POSTERIOR: output}
    if inputs is None:
        return readings
    detected, reported = detector_like_keypoints(
        batch.keypoints2d, batch.visible, size, inputs.keypoints, inputs.keypoint_stream
    )
    examples = masked_examples(rendered, inputs.masks, inputs.mask_stream)
    for name, terms_for in posteriors.items():
        terms = [terms_for(example) for example in examples]
        readings[name], _ = condition_batch(output, detected, reported, size, body64, config, terms)
    return readings


@dataclass
class _ShapeRecords:
    """Shape means and stds of each posterior, and the truth, batch by batch."""

    means: dict[str, list[torch.Tensor]]
    stds: dict[str, list[torch.Tensor]]
    truth: list[torch.Tensor]

    def add(self, name: str, prediction: BodyDistribution) -> None:
        shape = prediction.shape_distribution()
        self.means.setdefault(name, []).append(shape.mean.detach().double().cpu())
        self.stds.setdefault(name, []).append(shape.stddev.detach().double().cpu())


@torch.no_grad()
def evaluate_shape_batches(
    network: torch.nn.Module,
    batches: Sequence[RenderedBatch] | Iterator[RenderedBatch],
    body: BodyModel,
    evidence: bool,
    config: EvidenceConfig | None = None,
    keypoint_noise: DetectorNoise | None = None,
    mask_noise: MaskNoise | None = None,
    extra_terms_for: ExtraTermsFor = no_extra_terms,
    seed: int = 0,
    more_evidence: Mapping[str, ExtraTermsFor] | None = None,
) -> dict[str, ShapeScores]:
    """Shape scores of the network's posterior (and with ``evidence`` the evidence posterior's).

    Args:
        network: the distribution network (eval mode; a reader of proxies).
        batches: rendered synthetic batches (:func:`rendered_test_set`).
        body: body model on the network's device (float32).
        evidence: also condition on the detector-like keypoints (and ``extra_terms_for``).
        config: the evidence settings (default: :class:`EvidenceConfig`).
        keypoint_noise, mask_noise: the detector-like noise (defaults: their dataclasses').
        extra_terms_for: the terms beyond the keypoints for each example's mask.
        seed: seeds the keypoint noise (``seed``) and the mask noise (``seed + 1``).
        more_evidence: with ``evidence``, further evidence posteriors by name, each with its
            own terms beyond the keypoints, fitted to the same noisy keypoints and masks in
            the same pass (e.g. ``{"evidence_silhouette": silhouette_terms_for(body)}``).

    Returns:
        ``{"network": scores}`` and with ``evidence`` also ``"evidence"`` and every name of
        ``more_evidence``; examples whose fit fails score the network's posterior (as the
        ``--evidence`` rows do).
    """
    posteriors = {"evidence": extra_terms_for, **(more_evidence or {})}
    config = config or EvidenceConfig()
    body64 = float64_body(body)
    inputs = DetectorLikeInputs.seeded(seed, keypoint_noise, mask_noise) if evidence else None
    records = _ShapeRecords({}, {}, [])
    for rendered in batches:
        readings = read_posteriors(network, rendered, posteriors, config, body64, inputs)
        for name, reading in readings.items():
            records.add(name, reading)
        records.truth.append(rendered.batch.betas.detach().double().cpu())
    truth = torch.cat(records.truth)
    return {
        name: shape_scores(body64, torch.cat(means), torch.cat(records.stds[name]), truth)
        for name, means in records.means.items()
    }


def evaluate_shape_synthetic(
    checkpoint: Path,
    poses: Path | None,
    count: int,
    device: torch.device | str,
    evidence: bool,
    mirror_reading: bool = True,
    mask_noise: MaskNoise | None = None,
    extra_terms_for: ExtraTermsFor = no_extra_terms,
    more_evidence: Mapping[str, ExtraTermsFor] | None = None,
) -> dict[str, ShapeScores]:
    """:func:`evaluate_shape_batches` of ``checkpoint`` on the fixed synthetic test set
    (``count`` examples of the pose bank's test split, procedural poses without one), the
    network reading each proxy as it is and, with ``mirror_reading``, mirrored too (as the
    predictor and the ``--evidence`` rows read), with the checkpoint's stored evidence settings."""
    network, generator = network_and_generator(checkpoint, poses, device)
    reader = ProxyReader(
        network, ReadingConfig(mirror=mirror_reading), upright=False, body=generator.body
    )
    return evaluate_shape_batches(
        reader,
        rendered_test_set(generator, count),
        generator.body,
        evidence,
        config=stored_evidence_settings(checkpoint),
        mask_noise=mask_noise,
        extra_terms_for=extra_terms_for,
        more_evidence=more_evidence,
    )

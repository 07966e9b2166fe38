"""Shape from several photos of one person through the evidence posterior (synthetic).

:mod:`hkpd.evaluation.multi_view_shape` scores the *network's* shape Gaussians of ``views``
renders of each body. This module makes the same views and scores the shape of the evidence
posteriors instead: each view's network reading (as it is and mirrored, as the predictor
reads) is conditioned on the view's detector-like keypoints and, per posterior name, on
whatever evidence terms beyond them the view's detector-like mask gives (e.g. the silhouette
term), exactly as the ``--shape --evidence`` rows do for one photo
(:func:`hkpd.evaluation.shape_eval.evaluate_shape_batches`).

The result is one :class:`~hkpd.evaluation.multi_view_shape.MultiViewPredictions` per
posterior, so :func:`~hkpd.evaluation.multi_view_shape.multi_view_shape_table` scores them
like the network's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import torch

from hkpd.body import BodyModel
from hkpd.conditioning import EvidenceConfig
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.evidence_synthetic import condition_batch
from hkpd.evaluation.multi_view_shape import MULTI_VIEW_SEED, MultiViewPredictions
from hkpd.evaluation.shape_eval import (
    MASK_SEED_OFFSET,
    ExtraTermsFor,
    fit_config,
    masked_examples,
)
from hkpd.prediction.predictor import float64_body
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints
from hkpd.synthesis.generator import RenderedBatch, SyntheticDataGenerator, batch_seed
from hkpd.synthesis.mask_noise import MaskNoise

NETWORK_POSTERIOR = "network"
"""The name of the network's own posterior in :func:`predict_multi_view_evidence_shapes`."""


@torch.no_grad()
def predict_multi_view_evidence_shapes(
    reader: torch.nn.Module,
    generator: SyntheticDataGenerator,
    posteriors: Mapping[str, ExtraTermsFor],
    config: EvidenceConfig,
    bodies: int = 20,
    views: int = 5,
    seed: int = MULTI_VIEW_SEED,
    batch_size: int = 20,
    keypoint_noise: DetectorNoise | None = None,
    mask_noise: MaskNoise | None = None,
) -> dict[str, MultiViewPredictions]:
    """Render ``views`` images of ``bodies`` bodies and read their shapes through evidence.

    The bodies and views are those of
    :func:`hkpd.evaluation.multi_view_shape.predict_multi_view_shapes` with the same ``seed``
    and ``batch_size``.

    Args:
        reader: reads a batch of proxies into a :class:`hkpd.distributions.BodyDistribution`
            (e.g. :class:`hkpd.prediction.readings.proxy_reader.ProxyReader`), eval mode.
        generator: synthetic data generator (pose source: the pose bank's test split).
        posteriors: evidence posteriors by name, each with its terms beyond the keypoints
            (:func:`hkpd.evaluation.shape_eval.no_extra_terms`: keypoints only;
            :func:`~hkpd.evaluation.shape_eval.silhouette_terms_for`: the mask too).
        config: the evidence settings.
        bodies, views: bodies, and images per body (>= 1 each).
        seed: seeds the shapes, every view's batch, and the keypoint (``seed``) and mask
            (``seed + 1``) noise.
        batch_size: images rendered and read at a time.
        keypoint_noise, mask_noise: the detector-like noise (defaults: their dataclasses').

    Returns:
        ``{"network": ..., name: ... for every posterior}``: means and stds ``(views, bodies,
        K)`` and the true shapes ``(bodies, K)``. A view whose fit fails keeps the network's
        reading (as in :func:`hkpd.evaluation.evidence_synthetic.condition_batch`).
    """
    if bodies < 1 or views < 1 or batch_size < 1:
        raise ValueError(f"bodies, views and batch_size must be >= 1, got {bodies}, {views}, "
                         f"{batch_size}")  # fmt: skip
    names = [NETWORK_POSTERIOR, *posteriors]
    if len(set(names)) != len(names):
        raise ValueError(f"posterior names must differ from each other and from "
                         f"{NETWORK_POSTERIOR!r}, got {list(posteriors)}")  # fmt: skip
    keypoint_noise, mask_noise = keypoint_noise or DetectorNoise(), mask_noise or MaskNoise()
    body64 = float64_body(generator.body)
    true_betas = _body_shapes(generator, bodies, seed)
    keypoint_generator = torch.Generator().manual_seed(seed)
    mask_generator = torch.Generator().manual_seed(seed + MASK_SEED_OFFSET)
    chunks = (bodies + batch_size - 1) // batch_size
    means: dict[str, list[list[torch.Tensor]]] = {name: [] for name in names}
    stds: dict[str, list[list[torch.Tensor]]] = {name: [] for name in names}
    for view in range(views):
        for name in names:
            means[name].append([])
            stds[name].append([])
        for chunk, start in enumerate(range(0, bodies, batch_size)):
            betas = true_betas[start : start + batch_size]
            rendered = generator.generate(
                betas.shape[0], batch_seed(seed, view * chunks + chunk), betas
            )
            readings = _read_batch(
                reader, rendered, posteriors, config, body64,
                _DetectorNoises(keypoint_noise, keypoint_generator, mask_noise, mask_generator),
            )  # fmt: skip
            for name, reading in readings.items():
                shape = reading.shape_distribution()
                means[name][view].append(shape.mean.detach().float().cpu())
                stds[name][view].append(shape.stddev.detach().float().cpu())
    return {
        name: MultiViewPredictions(
            true_betas,
            torch.stack([torch.cat(per_view) for per_view in means[name]]),
            torch.stack([torch.cat(per_view) for per_view in stds[name]]),
        )
        for name in names
    }


@dataclass
class _DetectorNoises:
    """The detector-like keypoint and mask noise and their random streams."""

    keypoints: DetectorNoise
    keypoint_stream: torch.Generator
    masks: MaskNoise
    mask_stream: torch.Generator


def _read_batch(
    reader: torch.nn.Module,
    rendered: RenderedBatch,
    posteriors: Mapping[str, ExtraTermsFor],
    config: EvidenceConfig,
    body64: BodyModel,
    noises: _DetectorNoises,
) -> dict[str, BodyDistribution]:
    """The network's reading of one rendered batch and each evidence posterior of it."""
    batch = rendered.batch
    size = batch.proxy.shape[-1]
    output = reader(batch.proxy)
    readings = {NETWORK_POSTERIOR: output}
    detected, reported = detector_like_keypoints(
        batch.keypoints2d, batch.visible, size, noises.keypoints, noises.keypoint_stream
    )
    examples = masked_examples(rendered, noises.masks, noises.mask_stream)
    for name, terms_for in posteriors.items():
        terms = [terms_for(example) for example in examples]
        readings[name], _ = condition_batch(
            output, detected, reported, size, body64, fit_config(config, terms), terms
        )
    return readings


def _body_shapes(generator: SyntheticDataGenerator, bodies: int, seed: int) -> torch.Tensor:
    """``(bodies, K)`` shapes drawn from the generator's prior, as
    :func:`hkpd.evaluation.multi_view_shape.predict_multi_view_shapes` draws them."""
    shapes = torch.Generator().manual_seed(seed)
    body: BodyModel = generator.body
    return torch.randn(bodies, body.num_betas, generator=shapes) * generator.config.shape_std

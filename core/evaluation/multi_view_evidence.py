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

import torch

from hkpd.conditioning import EvidenceConfig
from hkpd.evaluation.multi_view_shape import MULTI_VIEW_SEED, MultiViewPredictions, body_shapes
from hkpd.evaluation.shape_eval import (
    NETWORK_POSTERIOR,
    DetectorLikeInputs,
    ExtraTermsFor,
    read_posteriors,
)
from hkpd.prediction.predictor import float64_body
from hkpd.synthesis.detector_noise import DetectorNoise
from hkpd.synthesis.generator import SyntheticDataGenerator, batch_seed
from hkpd.synthesis.mask_noise import MaskNoise


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
    inputs = DetectorLikeInputs.seeded(seed, keypoint_noise, mask_noise)
    body64 = float64_body(generator.body)
    true_betas = body_shapes(generator, bodies, seed)
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
            readings = read_posteriors(reader, rendered, posteriors, config, body64, inputs)
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

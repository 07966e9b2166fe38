"""The keypoint-evidence posterior on synthetic images, next to the network's own.

Each test example's exact keypoints get detector-like noise
(:func:`hkpd.synthesis.detector_noise.detector_like_keypoints`); the visible, reported ones are
the evidence. The conditioned posterior is packed into a :class:`BodyDistribution`, so every metric
of :func:`evaluate_prediction` (2D mode and samples errors, coverage, 3D errors) scores both
posteriors identically. Examples whose fit falls back score the network's posterior.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import torch

from hkpd.body import BodyModel
from hkpd.conditioning import (
    EvidenceConfig,
    EvidenceTerm,
    KeypointEvidence,
    condition_on_keypoints,
)
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.metrics import MILLIMETRES_PER_METRE
from hkpd.evaluation.prediction_metrics import evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.prediction.predictor import float64_body
from hkpd.synthesis.batch import TrainingBatch
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints


def condition_batch(
    output: BodyDistribution,
    detected: torch.Tensor,
    reported: torch.Tensor,
    crop_size: int,
    body64: BodyModel,
    config: EvidenceConfig,
    extra_terms: Sequence[Sequence[EvidenceTerm]] | None = None,
) -> tuple[BodyDistribution, torch.Tensor]:
    """The evidence posterior of every example of a batch (network's where the fit fails).

    Args:
        output: the network's ``B`` predictions (priors and starts).
        detected, reported: ``(B, 17, 2)`` keypoints in crop pixels and ``(B, 17)`` bool.
        crop_size: the crops' side, pixels.
        body64: float64 body model.
        config: the evidence settings.
        extra_terms: per example, the evidence beyond its keypoints (e.g. a silhouette term),
            weighed in the same fit with :meth:`EvidenceConfig.for_mask_evidence`'s settings,
            as the predictor weighs a mask; None: keypoints only.

    Returns:
        The conditioned output (same dtype and device as ``output``) and ``(B,)`` bool, which
        examples were conditioned.
    """
    conditioned = output.map(torch.clone)
    succeeded = torch.zeros(output.batch_size, dtype=torch.bool)
    for item in range(output.batch_size):
        start = output.rows(slice(item, item + 1)).detach().to("cpu")
        evidence = KeypointEvidence(detected[item].cpu(), reported[item].cpu(), crop_size)
        extra = () if extra_terms is None else extra_terms[item]
        settings = config.for_mask_evidence() if extra else config  # as the predictor's fit
        fit = condition_on_keypoints(body64, start, evidence, settings, extra_terms=extra)
        if fit.conditioned is None:
            continue
        succeeded[item] = True
        for mine, fitted in zip(conditioned.tensors(), fit.conditioned.tensors(), strict=True):
            mine[item] = fitted.to(mine.dtype)
    return conditioned, succeeded


@torch.no_grad()
def evaluate_evidence_batches(
    network: torch.nn.Module,
    batches: Iterable[TrainingBatch],
    body: BodyModel,
    config: EvidenceConfig | None = None,
    noise: DetectorNoise | None = None,
    num_samples: int = 25,
    seed: int = 0,
) -> dict[str, dict[str, float]]:
    """Mean metrics of the network's and of the evidence posterior on synthetic batches.

    Args:
        network: the distribution network (eval mode).
        batches: synthetic batches with ground truth.
        body: body model on the network's device (float32).
        config: the evidence settings.
        noise: the detector noise on the evidence keypoints.
        num_samples: samples per example.
        seed: seeds the noise and the sampling.

    Returns:
        ``{"network": metrics, "evidence": metrics}``; 2D errors in pixels at a 256 crop, 3D in
        millimetres; ``evidence`` also has ``conditioned`` (share of examples whose fit succeeded).
    """
    config = config or EvidenceConfig()
    noise = noise or DetectorNoise()
    body64 = float64_body(body)
    noise_generator = torch.Generator().manual_seed(seed)
    sums: dict[str, dict[str, list[torch.Tensor]]] = {"network": {}, "evidence": {}}
    for batch in batches:
        size = batch.proxy.shape[-1]
        output = network(batch.proxy)
        detected, reported = detector_like_keypoints(
            batch.keypoints2d, batch.visible, size, noise, noise_generator
        )
        conditioned, succeeded = condition_batch(output, detected, reported, size, body64, config)
        targets = targets_of(batch)
        for name, prediction in (("network", output), ("evidence", conditioned)):
            generator = torch.Generator(device=batch.proxy.device).manual_seed(seed)
            metrics = evaluate_prediction(prediction, body, targets, num_samples, size, generator)
            for metric, values in metrics.items():
                scaled = _in_reported_units(metric, values, size)
                sums[name].setdefault(metric, []).append(scaled.float().cpu())
        sums["evidence"].setdefault("conditioned", []).append(succeeded.float())
    return {
        name: {metric: float(torch.cat(values).nanmean()) for metric, values in metrics.items()}
        for name, metrics in sums.items()
    }


def _in_reported_units(metric: str, values: torch.Tensor, size: int) -> torch.Tensor:
    """2D errors in pixels at a 256 crop, 3D ones in millimetres (as :mod:`.synthetic`)."""
    if "_2d_" in metric:
        return values * (256.0 / size)
    if metric.startswith(("mpjpe", "pve_t_sc", "diversity")):
        return values * MILLIMETRES_PER_METRE
    return values

"""Evaluate a network on batches of synthetic examples (the fixed test set, or validation)."""

from __future__ import annotations

from collections.abc import Iterable

import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import CROP_SIZE
from hkpd.evaluation.metrics import MILLIMETRES_PER_METRE
from hkpd.evaluation.prediction_metrics import EvaluationTargets, evaluate_prediction
from hkpd.synthesis.batch import TrainingBatch

_METRES = ("mpjpe", "pve_t_sc", "diversity")


def _in_reported_units(name: str, value: float) -> float:
    """3D metrics are reported in millimetres; 2D errors are already in pixels."""
    return value * MILLIMETRES_PER_METRE if name.startswith(_METRES) else value


def targets_of(batch: TrainingBatch) -> EvaluationTargets:
    """The ground truth of a synthetic batch, for :func:`evaluate_prediction`."""
    return EvaluationTargets(
        joints3d=batch.joints3d,
        betas=batch.betas,
        keypoints2d=batch.keypoints2d,
        visible=batch.visible,
        body_pose=batch.body_pose,
    )


@torch.no_grad()
def evaluate_batches(
    network: torch.nn.Module,
    batches: Iterable[TrainingBatch],
    body: BodyModel,
    num_samples: int = 25,
    seed: int = 0,
    pass_crop_keypoints: bool = False,
) -> dict[str, float]:
    """Mean of every metric over all examples (NaN-aware: e.g. images with no hidden joint
    do not count for ``diversity_invisible``).

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` (put it in eval mode first).
        batches: synthetic batches with full ground truth.
        body: body model on the network's device.
        num_samples: bodies sampled per example for the sample metrics.
        seed: seeds the sampling, so repeated evaluations agree exactly.
        pass_crop_keypoints: call ``network(proxy, crop_keypoints=batch.keypoints2d)``, the
            keypoints each crop was framed on (for
            :class:`hkpd.prediction.readings.proxy_reader.ProxyReader`).

    Returns:
        ``{metric: mean}``: 3D metrics (MPJPE variants, PVE-T-SC, diversity) in millimetres,
        2D joint errors in pixels at a 256-pixel crop (rescaled from the batches' size).
    """
    sums: dict[str, float] = {}
    counts: dict[str, int] = {}
    generator = None
    for batch in batches:
        device = batch.proxy.device
        if generator is None:
            generator = torch.Generator(device=device).manual_seed(seed)
        if pass_crop_keypoints:
            output = network(batch.proxy, crop_keypoints=batch.keypoints2d)
        else:
            output = network(batch.proxy)
        targets = targets_of(batch)
        size = batch.proxy.shape[-1]
        results = evaluate_prediction(output, body, targets, num_samples, size, generator)
        for name, values in results.items():
            if name.startswith(("joint_error_2d", "joint_spread_2d")):
                values = values * (CROP_SIZE / size)  # pixels at a 256 crop, whatever the size
            finite = values[torch.isfinite(values)]
            sums[name] = sums.get(name, 0.0) + float(finite.sum())
            counts[name] = counts.get(name, 0) + int(finite.numel())
    return {
        name: _in_reported_units(name, sums[name] / counts[name]) if counts[name] else float("nan")
        for name in sums
    }

"""Experiment: which network reading the keypoint-evidence fit should start from.

On the fixed upright synthetic test split with BlazePose-like keypoint noise on the evidence (as
``hkpd-eval --evidence`` scores it), the evidence posterior is fitted from

1. the network's reading of the proxy as it is (the predictor until 2026-12-04),
2. the reading kept by the mirror reading (as it is or mirrored, whichever mode fits the shown
   keypoints better: :class:`hkpd.prediction.readings.mirror.MirrorChoosingReader`, the
   predictor's default since 2026-12-04),
3. both readings as two starts, the fit keeping the one of lower negative log posterior (as it
   does with a leaning person's crop and upright copy),

and the script prints the mean 2D mode error (px at 256), MPJPE-PA (mm), the samples' 2D error
and the pose coverage of each (25 samples per example).

    python docs/experiments/mirror_reading_evidence.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz --count 1000

Results: docs/model_history.md, section 5 ("Mirror reading").
"""

from __future__ import annotations

import numpy as np
import torch
from experiment_arguments import parse_experiment_arguments

from hkpd.conditioning import EvidenceConfig, KeypointEvidence, condition_on_keypoints
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.prediction_metrics import evaluate_prediction
from hkpd.evaluation.synthetic import targets_of
from hkpd.evaluation.test_set import fixed_batches, network_and_generator
from hkpd.prediction.predictor import float64_body
from hkpd.prediction.readings.mirror import MirrorChoosingReader
from hkpd.synthesis.detector_noise import DetectorNoise, detector_like_keypoints

METRICS = {
    "joint_error_2d_mode": ("mode 2D (px)", 256.0),
    "mpjpe_pa": ("MPJPE-PA (mm)", 1000.0),
    "joint_error_2d_samples": ("samples 2D (px)", 256.0),
    "pose_coverage_50": ("coverage 50 %", 1.0),
    "pose_coverage_90": ("coverage 90 %", 1.0),
}


def _conditioned(
    readings: list[BodyDistribution], detected, reported, size: int, body64, config
) -> BodyDistribution:
    """The evidence posterior of every example, fitted from the readings' starts (the
    first reading's own where the fit fails)."""
    conditioned = readings[0].map(torch.clone)
    for item in range(conditioned.batch_size):
        rows = [reading.rows(slice(item, item + 1)).tensors() for reading in readings]
        starts = BodyDistribution(*(torch.cat(parts) for parts in zip(*rows, strict=True)))
        evidence = KeypointEvidence(detected[item], reported[item], size)
        fit = condition_on_keypoints(body64, starts, evidence, config)
        if fit.conditioned is not None:
            for mine, fitted in zip(conditioned.tensors(), fit.conditioned.tensors(), strict=True):
                mine[item] = fitted.to(mine.dtype)
    return conditioned


def main(argv: list[str] | None = None) -> int:
    arguments = parse_experiment_arguments(__doc__.splitlines()[0], argv)
    torch.set_num_threads(1)
    network, generator = network_and_generator(arguments.checkpoint, arguments.poses, "cpu")
    network.eval()
    body = generator.body
    body64, config = float64_body(body), EvidenceConfig()
    reader = MirrorChoosingReader(network, body=body)
    noise, noise_generator = DetectorNoise(), torch.Generator().manual_seed(0)
    rows = ("as it is", "mirror reading (kept)", "both readings as starts")
    sums: dict[str, dict[str, list[np.ndarray]]] = {row: {} for row in rows}
    mirrored_share = []
    with torch.no_grad():
        for batch in fixed_batches(generator, arguments.count):
            size = int(batch.proxy.shape[-1])
            detected, reported = detector_like_keypoints(
                batch.keypoints2d, batch.visible, size, noise, noise_generator
            )
            kept = reader(batch.proxy)
            other = reader.last_other
            mirrored_share.append(reader.last_mirrored)
            as_it_is = network(batch.proxy)
            posteriors = {
                rows[0]: _conditioned([as_it_is], detected, reported, size, body64, config),
                rows[1]: _conditioned([kept], detected, reported, size, body64, config),
                rows[2]: _conditioned([kept, other], detected, reported, size, body64, config),
            }
            targets = targets_of(batch)
            for row, posterior in posteriors.items():
                draws = torch.Generator().manual_seed(0)
                metrics = evaluate_prediction(posterior, body, targets, 25, size, draws)
                for metric in METRICS:
                    values = metrics[metric].double().numpy()
                    scale = METRICS[metric][1]
                    if metric.startswith("joint_error_2d"):
                        scale = 256.0 / size
                    sums[row].setdefault(metric, []).append(values * scale)
    share = float(np.concatenate(mirrored_share).mean())
    print(f"evidence posterior on the upright synthetic split, {arguments.count} examples, "
          f"BlazePose-like noise; mirrored reading kept for {share:.1%}")  # fmt: skip
    print("| fit starts from | " + " | ".join(label for label, _ in METRICS.values()) + " |")
    print("|---|" + "---|" * len(METRICS))
    for row in rows:
        cells = [float(np.nanmean(np.concatenate(sums[row][m]))) for m in METRICS]
        print(f"| {row} | " + " | ".join(f"{c:.3f}" if c < 1 else f"{c:.2f}" for c in cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

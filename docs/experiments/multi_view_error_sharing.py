"""Why five photos of one body barely beat one (docs/shape.md, section 5).

Renders ``--bodies`` bodies five times each (the views of ``hkpd-eval --multi-view-shape``),
reads them through the network, the keypoint evidence posterior and the keypoint + mask
evidence posterior (:mod:`hkpd.evaluation.multi_view_evidence`), and prints per posterior:

- the share of the squared coefficient error that a body's five views have in common (the
  error of their average over the mean per-view error): near 1, averaging views cannot help;
- the regression slope of the posterior mean on the true coefficient, per coefficient (1: the
  mean follows the truth; near 0: it stays at the average body), and the scatter about it;
- PVE-T-SC of one view and of the mean of five;
- the product of the five Gaussians with the training prior counted once instead of five times
  (each view's Gaussian divided by the prior ``N(0, shape_std²)``, negative precisions dropped).

    python docs/experiments/multi_view_error_sharing.py assets/models/hkpd_hierarchical.pt \\
        --poses poses.npz --bodies 40
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from hkpd.body import BodyModel
from hkpd.evaluation.metrics import MILLIMETRES_PER_METRE, pve_t_sc
from hkpd.evaluation.multi_view_evidence import predict_multi_view_evidence_shapes
from hkpd.evaluation.multi_view_shape import MultiViewPredictions
from hkpd.evaluation.shape_eval import no_extra_terms, silhouette_terms_for
from hkpd.evaluation.test_set import network_and_generator, stored_evidence_settings
from hkpd.prediction.readings import ReadingConfig
from hkpd.prediction.readings.proxy_reader import ProxyReader


def pve_mm(body: BodyModel, betas: torch.Tensor, truth: torch.Tensor) -> float:
    """Mean PVE-T-SC of ``betas`` against ``truth`` (both ``(B, K)``), millimetres."""
    predicted, target = body.tpose(betas.float()), body.tpose(truth.float())
    return float(pve_t_sc(predicted, target).mean()) * MILLIMETRES_PER_METRE


def prior_counted_once(means: torch.Tensor, stds: torch.Tensor, prior_std: float) -> torch.Tensor:
    """``(B, K)`` mean of the product of ``(V, B, K)`` Gaussians with the prior ``N(0,
    prior_std²)`` counted once: every view's precision above the prior's is its likelihood."""
    precision, prior_precision = stds.pow(-2), prior_std**-2
    informative = precision > prior_precision
    total = prior_precision + ((precision - prior_precision) * informative).sum(0)
    return (means * precision * informative).sum(0) / total


def describe(
    name: str, prediction: MultiViewPredictions, body: BodyModel, prior_std: float
) -> None:
    means, truth = prediction.means.double(), prediction.true_betas.double()
    errors = means - truth
    shared = float(errors.mean(0).pow(2).sum() / errors.pow(2).mean(0).sum())
    slope = (means * truth).mean((0, 1)) / truth.pow(2).mean(0)
    scatter = (means - slope * truth).pow(2).mean((0, 1)).sqrt()
    print(f"{name}: shared error {shared:.2f}")
    print("  slopes  " + " ".join(f"{value:+.2f}" for value in slope))
    print("  scatter " + " ".join(f"{value:.2f}" for value in scatter))
    print("  mean std " + " ".join(f"{value:.2f}" for value in prediction.stds.mean((0, 1))))
    once = prior_counted_once(means, prediction.stds.double(), prior_std)
    print(
        f"  PVE-T-SC mm: one view {pve_mm(body, means[0], truth):.2f}, mean of five "
        f"{pve_mm(body, means.mean(0), truth):.2f}, prior counted once "
        f"{pve_mm(body, once, truth):.2f}"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkpoint", type=Path)
    parser.add_argument("--poses", type=Path)
    parser.add_argument("--bodies", type=int, default=40)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    network, generator = network_and_generator(args.checkpoint, args.poses, "cpu")
    reader = ProxyReader(network, ReadingConfig(mirror=True), upright=False, body=generator.body)
    posteriors = {
        "evidence": no_extra_terms,
        "evidence + mask": silhouette_terms_for(generator.body),
    }
    predictions = predict_multi_view_evidence_shapes(
        reader, generator, posteriors, stored_evidence_settings(args.checkpoint), args.bodies
    )
    for name, prediction in predictions.items():
        describe(name, prediction, generator.body, generator.config.shape_std)


if __name__ == "__main__":
    main()

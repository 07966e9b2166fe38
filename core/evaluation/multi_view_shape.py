"""Shape from several photos of one person, on synthetic data (the paper's multi-input protocol).

The paper's SSP-3D shape table scores, per person, the single-image predictions and two ways of
combining the predictions of up to 5 images of that person: the mean of the predicted means and
the probabilistic combination (the product of the shape Gaussians,
:mod:`hkpd.prediction.shape_combination`). Here the images are synthetic, so the true shape is
known exactly:

1. ``bodies`` shapes are drawn from the generator's shape prior ``N(0, shape_std^2)`` with their
   own seed;
2. view ``v`` of every body is batch ``v`` of the generator's stream with those betas fixed
   (:meth:`SyntheticDataGenerator.generate` with ``betas``): a different pose from the pose
   source (use the bank's *test* split), heading, camera, clothing, lighting, background and
   augmentations per view, the same body;
3. the network predicts a shape Gaussian per image; for every number of photos ``n`` and every
   subset of ``n`` of the ``views`` images the subset is combined both ways and scored with
   PVE-T-SC against the true T-pose; the single-image score is the mean over all images.

It also reports how sure the combined shape claims to be: the mean combined std of the
coefficients, the mean per-vertex shape uncertainty of the T-pose (metres, from sampled
shapes; on the first ``n`` views only, to keep it cheap) and the RMS of the coefficient errors
in units of the combined std (about 1 when the stds are honest, above 1 when over-confident).
For reference it scores the average body (all coefficients 0) too: a network that reads no shape
from the images scores about that.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import torch

from hkpd.body import BodyModel
from hkpd.evaluation.metrics import MILLIMETRES_PER_METRE, pve_t_sc
from hkpd.prediction.shape_combination import (
    combine_gaussians,
    shape_vertex_uncertainty,
)
from hkpd.synthesis.generator import SyntheticDataGenerator, batch_seed

MULTI_VIEW_SEED = 2025
"""Seed of the multi-view sets (another stream than the fixed test set's 2021)."""

MULTI_VIEW_COLUMNS = [
    "pve_t_sc_average_body",
    "pve_t_sc_single",
    "pve_t_sc_mean",
    "pve_t_sc_product",
    "shape_std_mean",
    "shape_std_product",
    "shape_uncertainty_product_mm",
    "shape_error_z_rms_product",
]

MULTI_VIEW_LABELS = {
    "pve_t_sc_average_body": "PVE-T-SC average body, betas 0 (mm)",
    "pve_t_sc_single": "PVE-T-SC single image (mm)",
    "pve_t_sc_mean": "PVE-T-SC mean of means (mm)",
    "pve_t_sc_product": "PVE-T-SC probabilistic (mm)",
    "shape_std_mean": "shape std, mean (RMS of photos)",
    "shape_std_product": "shape std, probabilistic",
    "shape_uncertainty_product_mm": "T-pose vertex uncertainty, probabilistic (mm)",
    "shape_error_z_rms_product": "beta error / std, probabilistic (RMS)",
}


@dataclass
class MultiViewPredictions:
    """The network's shape Gaussians for ``views`` images of each of ``bodies`` bodies.

    Attributes:
        true_betas: ``(bodies, K)`` the bodies' shapes.
        means: ``(views, bodies, K)`` predicted shape means.
        stds: ``(views, bodies, K)`` predicted shape stds.
    """

    true_betas: torch.Tensor
    means: torch.Tensor
    stds: torch.Tensor


@torch.no_grad()
def predict_multi_view_shapes(
    network: torch.nn.Module,
    generator: SyntheticDataGenerator,
    bodies: int = 100,
    views: int = 5,
    seed: int = MULTI_VIEW_SEED,
    batch_size: int = 50,
) -> MultiViewPredictions:
    """Render ``views`` images of each of ``bodies`` bodies and predict their shapes.

    Args:
        network: a :class:`hkpd.network.DistributionNetwork` in eval mode (its input size must
            be the generator's image size).
        generator: synthetic data generator (its pose source: the pose bank's test split).
        bodies: number of bodies (>= 1).
        views: images per body (>= 1).
        seed: seeds the bodies' shapes and every view's batch.
        batch_size: images rendered and predicted at a time.
    """
    if bodies < 1 or views < 1 or batch_size < 1:
        raise ValueError(f"bodies, views and batch_size must be >= 1, got {bodies}, {views}, "
                         f"{batch_size}")  # fmt: skip
    true_betas = body_shapes(generator, bodies, seed)
    means, stds = [], []
    for view in range(views):
        view_means, view_stds = [], []
        for chunk, start in enumerate(range(0, bodies, batch_size)):
            betas = true_betas[start : start + batch_size]
            index = view * ((bodies + batch_size - 1) // batch_size) + chunk
            batch = generator.generate(betas.shape[0], batch_seed(seed, index), betas).batch
            output = network(batch.proxy)
            view_means.append(output.shape_mean.float().cpu())
            view_stds.append(output.shape_std.float().cpu())
        means.append(torch.cat(view_means))
        stds.append(torch.cat(view_stds))
    return MultiViewPredictions(true_betas, torch.stack(means), torch.stack(stds))


def body_shapes(generator: SyntheticDataGenerator, bodies: int, seed: int) -> torch.Tensor:
    """``(bodies, K)`` shape coefficients drawn from the generator's shape prior
    ``N(0, shape_std²)`` with their own ``seed``: the bodies of the multi-view sets."""
    shapes = torch.Generator().manual_seed(seed)
    return (
        torch.randn(bodies, generator.body.num_betas, generator=shapes) * generator.config.shape_std
    )


@torch.no_grad()
def multi_view_shape_table(
    predictions: MultiViewPredictions,
    body: BodyModel,
    uncertainty_samples: int = 50,
    uncertainty_bodies: int | None = None,
) -> dict[str, dict[str, float]]:
    """Scores per number of photos ``n = 1 .. views`` (rows ``"1 photo"``, ``"2 photos"`` ...).

    Args:
        predictions: from :func:`predict_multi_view_shapes`.
        body: the :class:`hkpd.body.BodyModel` (CPU is fine).
        uncertainty_samples: T-pose meshes sampled per body for the per-vertex uncertainty.
        uncertainty_bodies: bodies whose per-vertex uncertainty is computed (the first ones;
            None: all).

    Returns:
        ``{row: {column: value}}`` with the columns of :data:`MULTI_VIEW_COLUMNS`: PVE-T-SC in
        millimetres (averaged over bodies and over every subset of ``n`` views), stds in
        shape-coefficient units (mean over coefficients and bodies), the uncertainty in mm.
    """
    views = predictions.means.shape[0]
    true_betas = predictions.true_betas.to(body.device, body.dtype)
    target = body.tpose(true_betas)

    def pve_mm(betas: torch.Tensor) -> float:
        predicted = body.tpose(betas.to(body.device, body.dtype))
        return float(pve_t_sc(predicted, target).mean()) * MILLIMETRES_PER_METRE

    single = sum(pve_mm(predictions.means[v]) for v in range(views)) / views
    average_body = pve_mm(torch.zeros_like(predictions.true_betas))
    rows: dict[str, dict[str, float]] = {}
    for count in range(1, views + 1):
        scores: dict[str, list[float]] = {"mean": [], "product": [], "z": []}
        stds: dict[str, list[float]] = {"mean": [], "product": []}
        for subset in itertools.combinations(range(views), count):
            means, deviations = predictions.means[list(subset)], predictions.stds[list(subset)]
            for method in ("mean", "product"):
                mean, std = combine_gaussians(means, deviations, method)
                scores[method].append(pve_mm(mean))
                stds[method].append(float(std.mean()))
                if method == "product":
                    z = (mean - predictions.true_betas) / std
                    scores["z"].append(float(z.pow(2).mean()))
        first_mean, first_std = combine_gaussians(
            predictions.means[:count], predictions.stds[:count], "product"
        )
        chosen = range(first_mean.shape[0] if uncertainty_bodies is None else uncertainty_bodies)
        uncertainty = [
            float(shape_vertex_uncertainty(body, mean, std, uncertainty_samples, seed=b).mean())
            for b, mean, std in zip(chosen, first_mean, first_std, strict=False)
        ]
        rows[f"{count} photo{'s' if count > 1 else ''}"] = {
            "pve_t_sc_average_body": average_body,
            "pve_t_sc_single": single,
            "pve_t_sc_mean": _average(scores["mean"]),
            "pve_t_sc_product": _average(scores["product"]),
            "shape_std_mean": _average(stds["mean"]),
            "shape_std_product": _average(stds["product"]),
            "shape_uncertainty_product_mm": _average(uncertainty) * MILLIMETRES_PER_METRE,
            "shape_error_z_rms_product": _average(scores["z"]) ** 0.5,
        }
    return rows


def _average(values: list[float]) -> float:
    return sum(values) / len(values) if values else float("nan")


def labelled(rows: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """The rows of :func:`multi_view_shape_table` with readable column names (for tables)."""
    return {
        row: {MULTI_VIEW_LABELS.get(name, name): value for name, value in values.items()}
        for row, values in rows.items()
    }

"""One body shape from several photos of the same person.

Every photo's posterior carries a diagonal Gaussian over the shape coefficients,
``N(beta; mu_i, diag(sigma_i^2))``. If the photos are independent views of one body, the
distribution of the shape given all of them is proportional to the product of these Gaussians
(the paper's *probabilistic combination*, the multi-input rows of its SSP-3D shape table), which
is again a diagonal Gaussian with, per coefficient,

    precision = sum_i 1 / sigma_i^2,    mean = (sum_i mu_i / sigma_i^2) / precision.

A photo the network is unsure about (large ``sigma_i``) therefore barely moves the result, and
N equally sure photos shrink the std by ``sqrt(N)``. The baseline (the paper's *mean*) averages
the means and ignores the stds; it has no rule for combining uncertainty, so it reports the
photos' root-mean-square std (as sure as one typical photo).

:func:`combine_shapes` returns a :class:`CombinedShape`: the combined coefficients, the T-pose
mesh of the mean shape and the per-vertex shape uncertainty (the mean distance of T-pose meshes
sampled from the combined Gaussian from their mean, as :mod:`hkpd.uncertainty` defines it, but
shape only: no pose enters).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal, Protocol

import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.prediction.sex_combination import combine_sexes
from hkpd.prediction.sex_latent import SexShapes
from hkpd.uncertainty import vertex_uncertainty

CombinationMethod = Literal["product", "mean"]
"""``"product"``: precision-weighted product of the Gaussians; ``"mean"``: mean of the means."""

COMBINATION_METHODS: tuple[CombinationMethod, ...] = ("product", "mean")

SHAPE_UNCERTAINTY_SAMPLES = 100
"""T-pose meshes sampled from the combined Gaussian for the per-vertex shape uncertainty."""


class ShapeDistribution(Protocol):
    """Anything with a diagonal shape Gaussian, e.g. a
    :class:`~hkpd.prediction.posterior.BodyPosterior`.

    Attributes:
        shape_mean: ``(K,)`` mean shape coefficients.
        shape_std: ``(K,)`` their standard deviations (> 0).
    """

    shape_mean: torch.Tensor
    shape_std: torch.Tensor


@dataclass(frozen=True)
class CombinedShape:
    """The shape of one person combined from ``count`` photos.

    Attributes:
        method: how the photos were combined (:data:`CombinationMethod`).
        count: number of photos combined.
        betas_mean: ``(K,)`` combined mean shape coefficients.
        betas_std: ``(K,)`` combined standard deviations.
        tpose_vertices: ``(V, 3)`` T-pose mesh of ``betas_mean`` in the camera-aligned body
            frame of :class:`~hkpd.prediction.posterior.BodyMeshes` (the body facing the camera:
            pelvis at the origin, x right, y down, z away from the viewer), metres.
        vertex_uncertainty: ``(V,)`` mean distance of sampled T-pose vertices from their mean,
            metres (pelvis-relative meshes, shape only).
        uncertainty_samples: T-pose meshes behind ``vertex_uncertainty``.
        faces: ``(F, 3)`` long triangle indices of the body model.
        sexes: with ``"product"`` of posteriors that hold sexes, the combined shape of each sex
            and the combined sex probabilities (:mod:`hkpd.prediction.sex_combination`:
            stated values counted once); ``betas_mean``/``betas_std`` are then the more
            probable sex's. None otherwise.
    """

    method: CombinationMethod
    count: int
    betas_mean: torch.Tensor
    betas_std: torch.Tensor
    tpose_vertices: torch.Tensor
    vertex_uncertainty: torch.Tensor
    uncertainty_samples: int
    faces: torch.Tensor
    sexes: SexShapes | None = None

    def __repr__(self) -> str:
        """One line: how and from how many photos, the sizes and the spreads (never the
        tensors)."""
        return (
            f"CombinedShape(method={self.method!r}, count={self.count}, "
            f"betas={tuple(self.betas_mean.shape)}, mean_std={self.mean_std:.3f}, "
            f"vertices={tuple(self.tpose_vertices.shape)}, "
            f"mean_uncertainty_m={float(self.vertex_uncertainty.mean()):.4f})"
        )

    @property
    def mean_std(self) -> float:
        """The mean of the ``K`` combined standard deviations (one number for tables)."""
        return float(self.betas_std.mean())


def stack_shape_distributions(
    distributions: Sequence[ShapeDistribution],
) -> tuple[torch.Tensor, torch.Tensor]:
    """The photos' shape Gaussians as ``means (N, K)`` and ``stds (N, K)``, checked.

    Raises:
        ValueError: no distributions, differing or non-1-D coefficient shapes, non-finite means,
            or stds that are not finite and > 0 (the message names the photo and coefficient).
    """
    if len(distributions) == 0:
        raise ValueError("combining shapes needs at least one photo's shape distribution, got none")
    means, stds = [], []
    expected = None
    for index, item in enumerate(distributions, start=1):
        mean = torch.as_tensor(item.shape_mean).detach().cpu()
        std = torch.as_tensor(item.shape_std).detach().cpu()
        if mean.dim() != 1 or std.shape != mean.shape:
            raise ValueError(
                f"photo {index}: shape mean and std must both be (K,) vectors, got "
                f"{tuple(mean.shape)} and {tuple(std.shape)}"
            )
        if expected is None:
            expected = mean.shape[0]
        elif mean.shape[0] != expected:
            raise ValueError(
                f"photo {index} has {mean.shape[0]} shape coefficients but photo 1 has "
                f"{expected}: all photos must come from models with the same body shape space"
            )
        means.append(mean)
        stds.append(std)
    return _checked(torch.stack(means), torch.stack(stds))


def _checked(means: torch.Tensor, stds: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``means`` and ``stds`` ``(N, ..., K)`` unchanged, or a ValueError naming the first bad
    photo (index along dim 0) and coefficient."""
    if means.shape != stds.shape or means.dim() < 2:
        raise ValueError(
            f"means and stds must both be (N, ..., K), got {tuple(means.shape)} and "
            f"{tuple(stds.shape)}"
        )
    if means.shape[0] == 0:
        raise ValueError("combining shapes needs at least one photo's shape distribution, got none")
    for name, values, good in (
        ("mean", means, torch.isfinite(means)),
        ("std", stds, torch.isfinite(stds) & (stds > 0)),
    ):
        if not bool(good.all()):
            photo, *rest = (int(i) for i in (~good).nonzero()[0])
            value = float(values[(photo, *rest)])
            need = "finite" if name == "mean" else "finite and > 0"
            raise ValueError(
                f"photo {photo + 1}: shape {name} of coefficient {rest[-1]} is {value}; it must be "
                f"{need}"
            )
    return means, stds


def product_of_gaussians(
    means: torch.Tensor, stds: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Precision-weighted product of N diagonal Gaussians, per coefficient.

    Args:
        means: ``(N, ..., K)`` means of N photos (leading dims after the first are batch dims).
        stds: ``(N, ..., K)`` standard deviations, finite and > 0.

    Returns:
        ``(mean, std)``, each ``(..., K)``: ``1/std^2 = sum_i 1/std_i^2`` and
        ``mean = std^2 * sum_i mean_i / std_i^2``.
    """
    means, stds = _checked(means, stds)
    precisions = stds.double().pow(-2)
    precision = precisions.sum(0)
    mean = (precisions * means.double()).sum(0) / precision
    return mean.to(means.dtype), precision.rsqrt().to(stds.dtype)


def mean_of_gaussians(means: torch.Tensor, stds: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The baseline: the mean of the N means, and the root-mean-square of the N stds.

    Args and returns as :func:`product_of_gaussians`.
    """
    means, stds = _checked(means, stds)
    return means.mean(0), stds.pow(2).mean(0).sqrt()


def combine_gaussians(
    means: torch.Tensor, stds: torch.Tensor, method: CombinationMethod = "product"
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`product_of_gaussians` or :func:`mean_of_gaussians` by name."""
    if method == "product":
        return product_of_gaussians(means, stds)
    if method == "mean":
        return mean_of_gaussians(means, stds)
    raise ValueError(f"combination method must be one of {', '.join(COMBINATION_METHODS)}, "
                     f"got {method!r}")  # fmt: skip


def tpose_meshes(body: BodyModel, betas: torch.Tensor) -> torch.Tensor:
    """``(B, V, 3)`` pelvis-relative T-pose meshes of ``betas (B, K)`` facing the camera
    (camera-aligned body frame, metres)."""
    betas = betas.to(device=body.device, dtype=body.dtype)
    with torch.no_grad():
        rest = body.tpose(betas) - body.rest_joints(betas)[:, :1]
    return rest @ FRONTAL_GLOBAL_ORIENT.to(rest).T


def shape_vertex_uncertainty(
    body: BodyModel,
    mean: torch.Tensor,
    std: torch.Tensor,
    n: int = SHAPE_UNCERTAINTY_SAMPLES,
    seed: int = 0,
) -> torch.Tensor:
    """``(V,)`` mean distance of ``n`` T-pose meshes with betas drawn from
    ``N(mean, diag(std^2))`` from their mean, metres (shape only; no pose).

    Args:
        body: the body model.
        mean, std: ``(K,)`` the shape Gaussian.
        n: meshes sampled (>= 2).
        seed: seeds the draw (the same seed gives the same answer).
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise ValueError(f"the number of shape samples must be an integer >= 2, got {n!r}")
    generator = torch.Generator().manual_seed(int(seed))
    noise = torch.randn(n, mean.shape[-1], generator=generator, dtype=torch.float64)
    betas = mean.double().cpu() + noise * std.double().cpu()
    return vertex_uncertainty(tpose_meshes(body, betas))


def combine_shapes(
    distributions: Sequence[ShapeDistribution],
    body: BodyModel,
    method: CombinationMethod = "product",
    uncertainty_samples: int = SHAPE_UNCERTAINTY_SAMPLES,
    seed: int = 0,
) -> CombinedShape:
    """Combine the shape Gaussians of several photos of one person.

    Args:
        distributions: N >= 1 posteriors (or anything with ``shape_mean``/``shape_std``
            ``(K,)``), e.g. ``[predictor.predict(p) for p in photos]``.
        body: the body model that turns coefficients into meshes (K must match it).
        method: ``"product"`` (the probabilistic combination) or ``"mean"`` (the baseline).
        uncertainty_samples: T-pose meshes sampled for the per-vertex uncertainty (>= 2).
        seed: seeds those samples.

    Returns:
        The :class:`CombinedShape`; with ``"product"`` of posteriors with sex as a latent, per
        sex (``CombinedShape.sexes``), the more probable sex's shape as its mean and std.

    Raises:
        ValueError: empty input, mismatched numbers of coefficients (between photos or with
            the body model), non-finite means, stds that are not finite and > 0, an unknown
            method.
    """
    means, stds = stack_shape_distributions(distributions)
    sexes = None
    if method == "product" and all(
        getattr(item, "sexes", None) is not None for item in distributions
    ):
        sexes = combine_sexes(list(distributions), body)  # type: ignore[arg-type]
    if sexes is None:
        return combine_shape_tensors(means, stds, body, method, uncertainty_samples, seed)
    sex = sexes.most_probable
    mean = sexes.means[sex].to(means.dtype)
    std = sexes.covariances[sex].diagonal().clamp_min(0).sqrt().to(stds.dtype)
    combined = combine_shape_tensors(mean[None], std[None], body, method, uncertainty_samples, seed)
    return replace(combined, count=int(means.shape[0]), sexes=sexes)


def combine_shape_tensors(
    means: torch.Tensor,
    stds: torch.Tensor,
    body: BodyModel,
    method: CombinationMethod = "product",
    uncertainty_samples: int = SHAPE_UNCERTAINTY_SAMPLES,
    seed: int = 0,
) -> CombinedShape:
    """:func:`combine_shapes` of the photos' shape Gaussians given as ``means`` and ``stds``
    ``(N, K)`` (checked the same way)."""
    means, stds = _checked(means, stds)
    if means.dim() != 2:
        raise ValueError(f"means and stds must be (N, K), got {tuple(means.shape)}")
    if means.shape[-1] != body.num_betas:
        raise ValueError(
            f"the photos have {means.shape[-1]} shape coefficients but the body model has "
            f"{body.num_betas}"
        )
    mean, std = combine_gaussians(means.cpu(), stds.cpu(), method)
    tpose = tpose_meshes(body, mean[None])[0]
    uncertainty = shape_vertex_uncertainty(body, mean, std, uncertainty_samples, seed)
    return CombinedShape(
        method=method,
        count=int(means.shape[0]),
        betas_mean=mean,
        betas_std=std,
        tpose_vertices=tpose,
        vertex_uncertainty=uncertainty.to(tpose.dtype),
        uncertainty_samples=uncertainty_samples,
        faces=body.faces,
    )

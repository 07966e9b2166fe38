"""``SilhouetteTerm``: the person's mask as evidence in the fit, a robust two-sided chamfer.

No differentiable renderer: the mask is turned once per photo into a distance map and a set of
boundary points, and the body into a few hundred surface points (farthest-point samples of the
mesh, posed exactly by :func:`~hkpd.conditioning.surface_points.vertex_subset_model`) projected
with the fit's weak-perspective camera. Two kinds of residual, one group each, in sigmas:

- **body → mask** (one per surface point ``p``): ``k(π p) · D_out(π p) / σ_out``, where
  ``D_out`` is the distance (crop pixels) from a pixel to the nearest pixel that may show the
  person (mask ≥ threshold, or unknown), zero inside, sampled bilinearly (continuous in the
  body, so forward differences see it), and ``k`` the bilinearly sampled ``known`` map (zero
  where the photo says nothing, and outside the crop). Every projected point must lie inside
  the mask; the body's outline is the set of points that can leave it first, so this is the
  outline-on-or-inside-the-mask half of the chamfer without choosing rim vertices (a choice
  that would jump as the pose changes).
- **mask → body** (one per sampled mask boundary point ``q``): ``max(min_p |q - π p| - τ, 0) /
  σ_in``: the mask's outline must be near the projected body (``τ`` absorbs the spacing of the
  surface samples). Boundary points are taken only where the photo is known and not next to an
  unknown pixel (an occluder's edge is no outline of the person).

The term is asymmetric (``σ_out < σ_in``) because clothing and hair make the mask larger than
the body: the body leaving the mask is strong evidence, the mask reaching beyond the body weak.
Each group is robustified by the Cauchy loss at ``robust_scale`` sigmas (another person, a
bag). The maths and the assumptions (tight clothing, one person) are in
``docs/shape.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
import torch.nn.functional as functional

from hkpd.camera_conventions import ndc_to_pixels
from hkpd.conditioning.evidence_term import PosedBodies
from hkpd.conditioning.surface_points import SurfaceSamples, farthest_point_indices

_UNKNOWN_MARGIN_PIXELS = 2
"""Mask boundary pixels within this many pixels of an unknown one are not the person's outline."""


@dataclass(frozen=True)
class SilhouetteEvidence:
    """The person's mask in the network's crop.

    Attributes:
        probability: ``(S, S)`` float64 in [0, 1], the probability that a crop pixel shows the
            person.
        known: ``(S, S)`` bool, False where the photo says neither body nor background (inside
            occluder boxes, outside the photo).
        crop_size: ``S``.
    """

    probability: torch.Tensor
    known: torch.Tensor
    crop_size: int

    def __post_init__(self) -> None:
        size = (self.crop_size, self.crop_size)
        if tuple(self.probability.shape) != size or tuple(self.known.shape) != size:
            raise ValueError(
                f"SilhouetteEvidence needs (S, S) = {size} maps, got probability "
                f"{tuple(self.probability.shape)} and known {tuple(self.known.shape)}"
            )

    @classmethod
    def from_arrays(
        cls, probability: np.ndarray, known: np.ndarray | None, device: torch.device | str = "cpu"
    ) -> SilhouetteEvidence:
        """From a ``(S, S)`` mask (e.g. ``NetworkInput.person_mask``) and its known map (None:
        all known), as float64 / bool tensors on ``device``."""
        if known is None:
            known = np.ones(probability.shape, dtype=bool)
        return cls(
            torch.as_tensor(np.asarray(probability, dtype=np.float64), device=device),
            torch.as_tensor(np.asarray(known, dtype=bool), device=device),
            int(probability.shape[0]),
        )


@dataclass(frozen=True)
class SilhouetteConfig:
    """Settings of the silhouette term (``docs/shape.md`` says how they were chosen).

    Attributes:
        outside_sigma: a body point outside the mask, noise of its distance to the mask, as a
            fraction of the crop side (0.03 is 7.7 px in a 256 crop). The defaults were chosen
            on synthetic validation data with masks that err as BlazePose's were measured to
            (``docs/shape.md``, 2026-12-05; before: 0.02 / 0.04 / 0.1, margin 0.02, chosen on
            lighter noise); an exact mask (a rendering) earns about a third of these sigmas
            and no margin.
        inside_sigma: a point of the body's outline inside the mask, noise of its distance to
            the mask's boundary, same units (larger: clothing and hair make the mask larger
            than the body).
        boundary_sigma: a mask boundary point away from the projected body, same units (the
            coarse pull for parts of the mask no outline point is near).
        inside_band: an outline point deeper inside the mask than about this (same units) is
            taken for one hidden behind another part of the body (the side of an arm in front of
            the torso): its distance saturates there, ``band · tanh(d / band)``.
        inside_margin: how much larger than the body the mask is expected to be (clothing, hair,
            a detector's blur), same units: an outline point this deep inside the mask, or a
            boundary point this far beyond the tolerance from the body, counts as touching.
        rim_width: how far from the outline a surface point still counts as on it: its weight
            is ``exp(-½ (n_z / rim_width)²)``, ``n_z`` the view component of its unit normal.
        boundary_tolerance: distance from a boundary point to the nearest projected surface
            point that counts as touching (the surface samples' spacing), same units.
        robust_scale: Cauchy scale of every group, in sigmas.
        reach_points: the first this many surface points (spread evenly too) are the body that
            a mask boundary point must be near (the coarse mask → body pull; fewer is cheaper).
        boundary_points: number of mask boundary points sampled (farthest-point samples).
        threshold: mask probability at and above which a pixel counts as the person.
    """

    outside_sigma: float = 0.03
    inside_sigma: float = 0.06
    boundary_sigma: float = 0.15
    inside_band: float = 0.012
    inside_margin: float = 0.01
    rim_width: float = 0.2
    boundary_tolerance: float = 0.004
    robust_scale: float = 3.0
    reach_points: int = 200
    boundary_points: int = 100
    threshold: float = 0.5

    def __post_init__(self) -> None:
        names = ("outside_sigma", "inside_sigma", "boundary_sigma", "inside_band", "rim_width")
        for name in (*names, "robust_scale", "threshold"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"SilhouetteConfig.{name} must be positive, got {value}")
        counts = (self.reach_points, self.boundary_points)
        if self.boundary_tolerance < 0 or self.inside_margin < 0 or min(counts) < 1:
            raise ValueError("SilhouetteConfig: tolerance >= 0 and point counts >= 1 are needed")


class SilhouetteTerm:
    """The mask as an :class:`~hkpd.conditioning.EvidenceTerm` (see the module docstring).

    Args:
        evidence: the mask in the crop the fit's cameras refer to.
        surface: the surface points of the fit's body model (``SurfaceSamples.of(body64)``,
            made once per model).
        config: the term's settings (defaults: :class:`SilhouetteConfig`).
    """

    name = "silhouette"
    needs_vertices = False

    def __init__(
        self,
        evidence: SilhouetteEvidence,
        surface: SurfaceSamples,
        config: SilhouetteConfig | None = None,
    ) -> None:
        config = config or SilhouetteConfig()
        self.config = config
        self.robust_scale: float | None = config.robust_scale
        self.crop_size = evidence.crop_size
        dtype, device = torch.float64, surface.points.device
        self.surface_vertices = surface.vertex_indices()
        maps = _mask_maps(evidence, config)
        self.outside_distance = torch.as_tensor(maps.outside_distance, dtype=dtype, device=device)
        self.inside_distance = torch.as_tensor(maps.inside_distance, dtype=dtype, device=device)
        self.known_map = torch.as_tensor(maps.known, dtype=dtype, device=device)
        boundary = torch.as_tensor(maps.boundary, dtype=dtype, device=device)
        chosen = farthest_point_indices(boundary, config.boundary_points)
        self.boundary = torch.zeros(config.boundary_points, 2, dtype=dtype, device=device)
        self.boundary_used = torch.zeros(config.boundary_points, dtype=dtype, device=device)
        self.boundary[: chosen.numel()] = boundary[chosen]
        self.boundary_used[: chosen.numel()] = 1.0
        pixels_per_unit = float(evidence.crop_size)
        self.outside_sigma_px = config.outside_sigma * pixels_per_unit
        self.inside_sigma_px = config.inside_sigma * pixels_per_unit
        self.inside_band_px = config.inside_band * pixels_per_unit
        self.boundary_sigma_px = config.boundary_sigma * pixels_per_unit
        self.margin_px = config.inside_margin * pixels_per_unit
        self.tolerance_px = (config.boundary_tolerance + config.inside_margin) * pixels_per_unit
        self.residual_shape = (surface.count + config.boundary_points, 2)

    @property
    def boundary_count(self) -> int:
        """Mask boundary points that are evidence (fewer than asked when the outline is short)."""
        return int(self.boundary_used.sum())

    def residuals(self, posed: PosedBodies) -> torch.Tensor:
        """``(N, B, P + boundary_points, 2)``: per surface point (outside the
        mask, on the outline inside the mask), then per boundary point (its gap to the body,
        and a zero)."""
        points, first, second = posed.surface[self.name].chunk(3, dim=-2)  # (N, B, P, 3) each
        pixels = ndc_to_pixels(posed.project(points), self.crop_size)  # (N, B, P, 2)
        normals = torch.linalg.cross(first - points, second - points)
        view = normals[..., 2] / normals.norm(dim=-1).clamp_min(1e-12)
        rim = torch.exp(-0.5 * (view / self.config.rim_width).square())
        known = _sample_bilinear(self.known_map, pixels)
        outside = (_sample_bilinear(self.outside_distance, pixels) - 0.5).clamp_min(0.0)
        inside = _sample_bilinear(self.inside_distance, pixels) - 0.5 - self.margin_px
        inside = inside.clamp_min(0.0)
        inside = self.inside_band_px * torch.tanh(inside / self.inside_band_px)
        body_to_mask = torch.stack(
            (outside / self.outside_sigma_px, rim * inside / self.inside_sigma_px), dim=-1
        ) * known.unsqueeze(-1)
        reach = pixels[..., : self.config.reach_points, :]  # (N, B, R, 2)
        across = reach[..., 0, None] - self.boundary[:, 0]  # (N, B, R, M)
        down = reach[..., 1, None] - self.boundary[:, 1]
        gaps = torch.addcmul(across * across, down, down)
        nearest = gaps.amin(dim=-2).clamp_min(1e-12).sqrt()  # (N, B, M)
        mask_to_body = (
            (nearest - self.tolerance_px).clamp_min(0.0) / self.boundary_sigma_px
        ) * self.boundary_used
        mask_to_body = torch.stack((mask_to_body, torch.zeros_like(mask_to_body)), dim=-1)
        return torch.cat((body_to_mask, mask_to_body), dim=-2)


@dataclass(frozen=True)
class _MaskMaps:
    """What the term reads of one mask: ``outside_distance`` (to the nearest pixel that may
    show the person), ``inside_distance`` (from a person pixel to the nearest known background
    one) and ``known`` ``(S, S)`` float64 maps, and ``boundary`` ``(M, 2)`` pixel ``(u, v)`` of
    the outline's pixels."""

    outside_distance: np.ndarray
    inside_distance: np.ndarray
    known: np.ndarray
    boundary: np.ndarray


def _mask_maps(evidence: SilhouetteEvidence, config: SilhouetteConfig) -> _MaskMaps:
    """The distance map (to pixels that may show the person: in the mask or unknown) and the
    outline pixels of the known mask that do not touch an unknown pixel."""
    probability = evidence.probability.detach().cpu().numpy()
    known = evidence.known.detach().cpu().numpy().astype(bool)
    person = (probability >= config.threshold) & known
    maybe_person = person | ~known
    outside = cv2.distanceTransform(
        (~maybe_person).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE
    ).astype(np.float64)
    inside = cv2.distanceTransform(
        (person | ~known).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE
    ).astype(np.float64)
    if not person.any():  # an empty mask (no detection) is no evidence, not "nobody here"
        outside, inside = np.zeros_like(outside), np.zeros_like(inside)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    interior = cv2.erode(person.astype(np.uint8), cross).astype(bool)
    square = np.ones((2 * _UNKNOWN_MARGIN_PIXELS + 1,) * 2, dtype=np.uint8)
    near_unknown = cv2.dilate((~known).astype(np.uint8), square).astype(bool)
    rows, columns = np.nonzero(person & ~interior & ~near_unknown)
    boundary = np.stack((columns, rows), axis=-1).astype(np.float64)
    return _MaskMaps(outside, inside, known.astype(np.float64), boundary)


def _sample_bilinear(image: torch.Tensor, pixels: torch.Tensor) -> torch.Tensor:
    """``image (S, S)`` at ``pixels (..., 2)`` ``(u, v)`` (centres at integers), bilinear, zero
    outside the image: ``(...)``."""
    size = image.shape[-1]
    grid = pixels * (2.0 / (size - 1)) - 1.0
    sampled = functional.grid_sample(
        image[None, None],
        grid.reshape(1, 1, -1, 2),
        mode="bilinear",
        padding_mode="zeros",
        align_corners=True,
    )
    return sampled.reshape(pixels.shape[:-1])

"""Detector-like person masks from exact silhouettes: boundary offset and jitter, dilation for
clothing and hair, missed thin parts, spurious blobs, soft edges.

Used to feed the silhouette evidence realistic masks on synthetic images (whose exact silhouette
is known), as :mod:`hkpd.synthesis.detector_noise` does for the keypoints. The steps, applied
to each ``(S, S)`` silhouette in turn (lengths in pixels at a 256-pixel crop, scaled to ``S``):

1. **Boundary offset.** The silhouette is blurred with a Gaussian of ``boundary_sigma_px`` and
   thresholded at ``Phi(-d / sigma)``: on a straight edge the blurred silhouette is
   ``Phi(x / sigma)`` (``x`` the signed distance inside), so the new edge lies exactly ``d``
   pixels outside the old one (inside for ``d < 0``). ``d`` is the example's dilation
   (``dilation_px`` plus Gaussian ``dilation_jitter_px`` per example: clothing and hair make a
   segmenter's mask larger than the body) plus a smooth random field of std
   ``boundary_noise_px`` (a wavy boundary, correlated over about ``S / noise_cells`` pixels).
   Parts thinner than about the blur (fingers, a distant wrist) fade below the threshold and
   go missing, as they do for a segmenter.
2. **Missed thin parts.** With probability ``thin_part_miss_rate`` an example's mask is opened
   (eroded, then dilated) by ``thin_part_px``: what is narrower than twice that disappears.
3. **Spurious blobs.** A Poisson number (mean ``blob_rate``) of discs of radius uniform in
   ``blob_radius_px`` at uniform positions in the crop (another person, a bag, a shadow).
4. **Soft edges.** The binary mask is blurred by ``edge_softness_px`` into a probability in
   [0, 1], as a segmenter's output is.

Pixels where ``known`` is False (occluder boxes, outside the photo) keep their input value:
the photo says nothing there, and the evidence ignores them.

The defaults reproduce, as far as this model can, the errors measured for BlazePose against
coco_mini's COCO masks for people alone in the photo (train2017, docs/shape.md section 1;
chosen by ``docs/experiments/mask_noise_calibration.py`` on the pose bank's ``val`` subjects,
with the exact silhouette in the COCO mask's place). BlazePose: mean IoU 0.84, edge offsets
spread by 3.05 px, 2.4 % of the person missed in far parts, 0.57 spurious blobs per person.
These settings: IoU 0.81, spread 2.4 px, 1.2 % missed, 0.40 blobs (200 examples). No setting
of this model matches both the IoU and the spread (a spread of 2.8 px gives IoU 0.77): COCO's
coarse polygons are part of BlazePose's measured errors, and the rendered bodies are slimmer in
the crop than COCO's clothed people, so the same edge noise costs them more IoU. The boundary
lies 0.3 px outside the body on average (dilation 0.5 px: clothing and hair; against COCO's
generous polygons BlazePose's edge is 1.35 px inside). Until 2026-12-05 the defaults were a
lighter first guess (boundary noise 1.5 px, dilation 1.5 ± 1.0 px, blur 4 px, thin parts lost
in 30 % of crops at 2 px, 0.2 blobs of 6-20 px: IoU 0.84, spread 1.8 px, 0.19 blobs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F

REFERENCE_CROP = 256
"""The crop size the pixel lengths of :class:`MaskNoise` refer to."""


@dataclass(frozen=True)
class MaskNoise:
    """The mask-noise model (lengths in pixels at a 256-pixel crop; see the module's steps).

    Attributes:
        dilation_px: mean outward offset of the boundary (negative: inward).
        dilation_jitter_px: per-example Gaussian std of that offset.
        boundary_noise_px: std of the smooth random offset along the boundary.
        boundary_sigma_px: the blur that moves the boundary; offsets beyond about twice it
            are clipped by the blur's reach.
        noise_cells: the offset field is drawn on a ``noise_cells²`` grid and upsampled.
        thin_part_miss_rate: share of examples whose thin parts are removed.
        thin_part_px: opening radius of that removal.
        blob_rate: mean number of spurious blobs per example.
        blob_radius_px: ``(low, high)`` blob radii.
        edge_softness_px: blur of the final mask into a probability (0: binary).
    """

    dilation_px: float = 0.5
    dilation_jitter_px: float = 1.2
    boundary_noise_px: float = 2.2
    boundary_sigma_px: float = 5.0
    noise_cells: int = 16
    thin_part_miss_rate: float = 0.5
    thin_part_px: int = 3
    blob_rate: float = 0.5
    blob_radius_px: tuple[float, float] = (4.0, 14.0)
    edge_softness_px: float = 1.0

    def __post_init__(self) -> None:
        if self.boundary_sigma_px <= 0 or self.noise_cells < 1 or self.thin_part_px < 0:
            raise ValueError("boundary_sigma_px and noise_cells must be positive")
        for name in ("dilation_jitter_px", "boundary_noise_px", "blob_rate", "edge_softness_px"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not 0.0 <= self.thin_part_miss_rate <= 1.0:
            raise ValueError(
                f"thin_part_miss_rate must be in [0, 1], got {self.thin_part_miss_rate}"
            )
        low, high = self.blob_radius_px
        if not 0 < low <= high:
            raise ValueError(f"blob_radius_px must be 0 < low <= high, got {self.blob_radius_px}")


NO_MASK_NOISE = MaskNoise(
    dilation_px=0.0,
    dilation_jitter_px=0.0,
    boundary_noise_px=0.0,
    thin_part_miss_rate=0.0,
    blob_rate=0.0,
    edge_softness_px=0.0,
)
"""The exact silhouette (thin parts below the boundary blur excepted): for tests and bounds."""


def detector_like_masks(
    silhouettes: torch.Tensor,
    known: torch.Tensor,
    noise: MaskNoise,
    generator: torch.Generator,
) -> torch.Tensor:
    """Degrade exact silhouettes as a segmenter would.

    Args:
        silhouettes: ``(B, S, S)`` bool, the exact silhouettes in crop pixels.
        known: ``(B, S, S)`` bool, where the photo says body or background; elsewhere the
            input is returned unchanged.
        noise: the noise model.
        generator: a CPU generator (results do not depend on the device).

    Returns:
        ``(B, S, S)`` float32 person probability in [0, 1] on ``silhouettes``' device.
    """
    if silhouettes.dim() != 3 or silhouettes.shape[-1] != silhouettes.shape[-2]:
        raise ValueError(f"silhouettes must be (B, S, S), got {tuple(silhouettes.shape)}")
    if known.shape != silhouettes.shape:
        raise ValueError(f"known must be {tuple(silhouettes.shape)}, got {tuple(known.shape)}")
    device = silhouettes.device
    exact = silhouettes.detach().cpu().float()
    scale = exact.shape[-1] / REFERENCE_CROP
    mask = _offset_boundary(exact, noise, scale, generator)
    mask = _remove_thin_parts(mask, noise, scale, generator)
    mask = _add_blobs(mask, noise, scale, generator)
    probability = _blur(mask, noise.edge_softness_px * scale).clamp(0.0, 1.0)
    known_cpu = known.detach().cpu()
    return torch.where(known_cpu, probability, exact).to(device)


def _offset_boundary(
    exact: torch.Tensor, noise: MaskNoise, scale: float, generator: torch.Generator
) -> torch.Tensor:
    """Step 1: the boundary moved by the example's dilation plus the smooth offset field."""
    count, size = exact.shape[0], exact.shape[-1]
    sigma = noise.boundary_sigma_px * scale
    jitter = torch.randn(count, generator=generator)
    dilation = noise.dilation_px + noise.dilation_jitter_px * jitter
    field = torch.randn(count, 1, noise.noise_cells, noise.noise_cells, generator=generator)
    field = F.interpolate(field, size=(size, size), mode="bicubic", align_corners=False)[:, 0]
    field = field / field.flatten(1).std(1).clamp_min(1e-6)[:, None, None]
    offset = dilation[:, None, None] * scale + noise.boundary_noise_px * scale * field
    threshold = 0.5 * torch.erfc(offset / (sigma * math.sqrt(2.0)))  # Phi(-offset / sigma)
    return (_blur(exact, sigma) > threshold).float()


def _remove_thin_parts(
    mask: torch.Tensor, noise: MaskNoise, scale: float, generator: torch.Generator
) -> torch.Tensor:
    """Step 2: a morphological opening of the chosen examples."""
    chosen = torch.rand(mask.shape[0], generator=generator) < noise.thin_part_miss_rate
    radius = round(noise.thin_part_px * scale)
    if radius < 1 or not bool(chosen.any()):
        return mask
    kernel = 2 * radius + 1
    picked = mask[chosen][:, None]
    eroded = -F.max_pool2d(-picked, kernel, stride=1, padding=radius)
    opened = F.max_pool2d(eroded, kernel, stride=1, padding=radius)[:, 0]
    result = mask.clone()
    result[chosen] = opened
    return result


def _add_blobs(
    mask: torch.Tensor, noise: MaskNoise, scale: float, generator: torch.Generator
) -> torch.Tensor:
    """Step 3: discs at random places, a Poisson number per example."""
    count, size = mask.shape[0], mask.shape[-1]
    blobs = torch.poisson(torch.full((count,), noise.blob_rate), generator=generator).long()
    if int(blobs.sum()) == 0:
        return mask
    rows = torch.arange(size, dtype=torch.float32)
    result = mask.clone()
    low, high = (r * scale for r in noise.blob_radius_px)
    for index in blobs.nonzero().flatten().tolist():
        for _ in range(int(blobs[index])):
            centre = torch.rand(2, generator=generator) * size
            radius = low + (high - low) * float(torch.rand(1, generator=generator))
            inside = (rows[:, None] - centre[1]) ** 2 + (rows[None] - centre[0]) ** 2
            result[index] = torch.where(inside <= radius**2, 1.0, result[index])
    return result


def _blur(images: torch.Tensor, sigma: float) -> torch.Tensor:
    """``(B, S, S)`` images blurred by a separable Gaussian of ``sigma`` pixels (0: as is),
    zero outside the image."""
    if sigma <= 0:
        return images
    radius = max(1, math.ceil(3 * sigma))
    taps = torch.arange(-radius, radius + 1, dtype=torch.float32)
    kernel = torch.exp(-0.5 * (taps / sigma) ** 2)
    kernel = kernel / kernel.sum()
    planes = images[:, None].float()
    planes = F.conv2d(planes, kernel.view(1, 1, 1, -1), padding=(0, radius))
    planes = F.conv2d(planes, kernel.view(1, 1, -1, 1), padding=(radius, 0))
    return planes[:, 0]

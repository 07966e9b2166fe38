"""Lights for synthetic renders: the :class:`Lighting` parameters, their sampler and the
Lambert + Blinn-Phong shading of face albedos.

Intensity ranges follow the paper's supplement (PyTorch3D Phong lighting): ambient and diffuse
intensities uniform in [0.4, 0.8], specular in [0, 0.5]. Not given there, our choices: one
directional light from the camera's side (within 70° of the viewing axis, so the visible side of
the body is lit), a near-white light colour (each channel uniform in [0.8, 1]) and a Blinn-Phong
shininess uniform in [10, 80] (PyTorch3D's default material uses 64).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import torch

AMBIENT_RANGE = (0.4, 0.8)
DIFFUSE_RANGE = (0.4, 0.8)
SPECULAR_RANGE = (0.0, 0.5)
SHININESS_RANGE = (10.0, 80.0)
LIGHT_COLOUR_RANGE = (0.8, 1.0)
MAX_LIGHT_ANGLE_DEG = 70.0
"""Largest angle between the light direction and the direction back to the camera (-z)."""


@dataclass
class Lighting:
    """One directional light per image, camera frame (OpenCV: x right, y down, z forward).

    Attributes:
        ambient: ``(B,)`` ambient intensity.
        diffuse: ``(B,)`` diffuse (Lambert) intensity.
        specular: ``(B,)`` specular (Blinn-Phong) intensity.
        direction: ``(B, 3)`` unit vector from the surface towards the light (a light in front
            of the body has a negative z component).
        colour: ``(B, 3)`` light colour in [0, 1], multiplies all three terms.
        shininess: ``(B,)`` Blinn-Phong exponent.
    """

    ambient: torch.Tensor
    diffuse: torch.Tensor
    specular: torch.Tensor
    direction: torch.Tensor
    colour: torch.Tensor
    shininess: torch.Tensor

    @property
    def batch_size(self) -> int:
        return int(self.ambient.shape[0])

    def to(self, device: torch.device | str) -> Lighting:
        """A copy with every tensor on ``device``."""
        return Lighting(**{f.name: getattr(self, f.name).to(device) for f in fields(self)})

    def check(self, batch: int) -> None:
        """Raise ValueError unless every field has the documented shape for ``batch`` images."""
        expected = {
            "ambient": (batch,),
            "diffuse": (batch,),
            "specular": (batch,),
            "direction": (batch, 3),
            "colour": (batch, 3),
            "shininess": (batch,),
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if tuple(value.shape) != shape:
                raise ValueError(
                    f"Lighting.{name} has shape {tuple(value.shape)}, expected {shape} for a "
                    f"batch of {batch} images (use sample_lighting({batch}, ...))"
                )


def _uniform(
    count: int, bounds: tuple[float, float], generator: torch.Generator | None, device
) -> torch.Tensor:
    low, high = bounds
    return low + (high - low) * torch.rand(count, generator=generator, device=device)


def sample_lighting(
    count: int, generator: torch.Generator | None = None, device: torch.device | str = "cpu"
) -> Lighting:
    """Random lights with the paper's intensity ranges (see the module docstring).

    Args:
        count: number of images B.
        generator: torch random generator (None: the global one); the numbers are drawn on its
            device and moved to ``device``.
        device: where the tensors live.

    Returns:
        :class:`Lighting` with ``(B,)`` / ``(B, 3)`` float32 tensors.
    """
    target = torch.device(device)
    device = generator.device if generator is not None else target
    ambient = _uniform(count, AMBIENT_RANGE, generator, device)
    diffuse = _uniform(count, DIFFUSE_RANGE, generator, device)
    specular = _uniform(count, SPECULAR_RANGE, generator, device)
    shininess = _uniform(count, SHININESS_RANGE, generator, device)
    # Direction uniform on the spherical cap around -z (towards the camera).
    cos_max = math.cos(math.radians(MAX_LIGHT_ANGLE_DEG))
    cos_angle = _uniform(count, (cos_max, 1.0), generator, device)
    sin_angle = (1.0 - cos_angle**2).clamp(min=0.0).sqrt()
    azimuth = _uniform(count, (0.0, 2.0 * math.pi), generator, device)
    direction = torch.stack(
        (sin_angle * azimuth.cos(), sin_angle * azimuth.sin(), -cos_angle), dim=1
    )
    colour = LIGHT_COLOUR_RANGE[0] + (LIGHT_COLOUR_RANGE[1] - LIGHT_COLOUR_RANGE[0]) * torch.rand(
        count, 3, generator=generator, device=device
    )
    return Lighting(ambient, diffuse, specular, direction, colour, shininess).to(target)


def shade(
    albedo: torch.Tensor,
    normals: torch.Tensor,
    view: torch.Tensor,
    lighting: Lighting,
) -> torch.Tensor:
    """Lambert + Blinn-Phong colour of N surface elements (faces or pixels) per image.

    ``colour = light * (albedo * (ambient + diffuse * max(n.l, 0)) + specular * max(n.h, 0)^s)``
    with ``h = normalize(l + v)``, the specular term only where ``n.l > 0``; clamped to [0, 1].
    Tensors are component-major (x, y, z or r, g, b along dim 1) so that the per-component
    arithmetic runs on contiguous planes.

    Args:
        albedo: ``(B, 3, N)`` in [0, 1].
        normals: ``(B, 3, N)`` unit normals facing the camera.
        view: ``(B, 3, N)`` or ``(B, 3, 1)`` unit vectors from the surface to the camera.
        lighting: B lights.

    Returns:
        ``(B, 3, N)`` colours in [0, 1].
    """
    light = lighting.direction[:, :, None].to(normals)
    lambert = (normals * light).sum(dim=1, keepdim=True)
    halfway = view + light
    halfway = halfway * (halfway * halfway).sum(dim=1, keepdim=True).clamp_(min=1e-30).rsqrt_()
    highlight = (normals * halfway).sum(dim=1, keepdim=True).clamp_(min=0.0)
    highlight = highlight.pow_(lighting.shininess[:, None, None]) * (lambert > 0)
    diffuse = lambert.clamp_(min=0.0).mul_(lighting.diffuse[:, None, None])
    diffuse += lighting.ambient[:, None, None]
    colour = torch.addcmul(highlight * lighting.specular[:, None, None], albedo, diffuse)
    return colour.mul_(lighting.colour[:, :, None]).clamp_(0.0, 1.0)

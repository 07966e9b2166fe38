"""The predicted mode mesh drawn over the photo, with the predicted camera: how well it fits.

The network's camera is weak-perspective on the crop: crop NDC ``= s (X_xy + t)``. A
perspective camera placed :data:`OVERLAY_DISTANCE_M` away with focal length ``s S / 2 · D``
reproduces that projection on an ``S``-pixel render of the crop box to well under a pixel
(the body's depth is a thousandth of the distance), so the ordinary rasteriser draws it. The
result is an RGBA picture of the crop box (transparent off the body) that callers paste over the
photo at :attr:`FitOverlay.box`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hkpd.prediction.posterior import BodyPosterior
from hkpd.rendering import Lighting, MeshRenderer

OVERLAY_DISTANCE_M = 1000.0
OVERLAY_COLOUR = (0.55, 0.78, 1.0)
"""Light blue albedo of the overlaid mesh."""


@dataclass(frozen=True)
class FitOverlay:
    """An RGBA render of the mode over the crop box.

    Attributes:
        rgba: ``(S, S, 4)`` uint8; alpha 255 on the body, 0 elsewhere.
        box: ``(x0, y0, x1, y1)`` the crop box in original-photo pixels (pixel-edge
            coordinates) that the render covers.
    """

    rgba: np.ndarray
    box: tuple[float, float, float, float]

    def with_opacity(self, opacity: float) -> np.ndarray:
        """The RGBA picture with the body's alpha scaled to ``opacity`` in [0, 1]."""
        out = self.rgba.copy()
        out[..., 3] = np.round(out[..., 3].astype(np.float32) * float(np.clip(opacity, 0, 1)))
        return out


def _front_light() -> Lighting:
    direction = torch.tensor([[-0.3, -0.5, 0.81]])  # from the viewer's upper left
    return Lighting(
        ambient=torch.tensor([0.5]),
        diffuse=torch.tensor([0.6]),
        specular=torch.tensor([0.1]),
        direction=-direction / direction.norm(dim=1, keepdim=True),
        colour=torch.ones(1, 3),
        shininess=torch.tensor([20.0]),
    )


@torch.no_grad()
def render_fit_overlay(posterior: BodyPosterior, size: int = 384) -> FitOverlay:
    """Render ``posterior``'s mode over its crop box (see the module docstring).

    Args:
        posterior: a posterior from :class:`hkpd.prediction.Predictor`.
        size: side of the render in pixels.
    """
    if size < 8:
        raise ValueError(f"size must be at least 8 pixels, got {size}")
    mode = posterior.mode()
    vertices = mode.vertices[0].float().cpu()
    scale, tx, ty = (float(v) for v in posterior.camera.float().cpu())
    placed = vertices + torch.tensor([tx, ty, OVERLAY_DISTANCE_M])
    focal = scale * size / 2.0 * OVERLAY_DISTANCE_M
    faces = posterior.body.faces.cpu()
    renderer = MeshRenderer(faces, image_size=size)
    albedo = torch.tensor(OVERLAY_COLOUR).expand(1, faces.shape[0], 3)
    output = renderer.render(placed[None], torch.tensor([focal]), albedo, _front_light())
    rgb = (output.rgb[0].permute(1, 2, 0).clamp(0, 1).numpy() * 255).round().astype(np.uint8)
    alpha = output.mask[0].numpy().astype(np.uint8) * 255
    x0, y0, x1, y1 = posterior.crop.box
    return FitOverlay(np.dstack([rgb, alpha]), (float(x0), float(y0), float(x1), float(y1)))

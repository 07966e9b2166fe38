"""The camera conventions shared by synthetic data, the network, the losses and the predictor.

Camera frame (OpenCV): x right, y down, z forward, metres. A body's ``global_orient`` maps the
body frame (SMPL axes: Y up, facing +Z) to the camera frame, so a person standing upright and
facing the camera has ``global_orient = FRONTAL_GLOBAL_ORIENT`` (a half turn about x).

Images are square crops of ``CROP_SIZE`` pixels; pixel ``(u, v)`` has u to the right and v down,
and pixel centres sit at integer coordinates (the top-left pixel's centre is ``(0, 0)``).

Synthetic images use a perspective camera with focal length ``SYNTHETIC_FOCAL_PX`` and the
principal point at the crop centre. The network predicts a weak-perspective camera
``[s, tx, ty]`` acting on root-relative 3D points ``X`` already rotated into the camera frame:
``ndc = s * (X_xy + [tx, ty])``, and pixels ``= (ndc + 1) * CROP_SIZE / 2 - 0.5``, so
``ndc = -1 .. 1`` spans the crop edge to edge.
"""

from __future__ import annotations

import torch

CROP_SIZE = 256
"""Side of the square network input, in pixels."""

SYNTHETIC_FOCAL_PX = 300.0
"""Focal length of the synthetic perspective camera at ``CROP_SIZE`` pixels (paper's supplement)."""

FRONTAL_GLOBAL_ORIENT = torch.tensor([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
"""Global rotation of an upright body facing the camera (SMPL Y-up, +Z-facing to OpenCV)."""


def ndc_to_pixels(ndc: torch.Tensor, size: int = CROP_SIZE) -> torch.Tensor:
    """``(..., 2)`` normalised coordinates in [-1, 1] to pixel coordinates in a ``size`` crop."""
    return (ndc + 1.0) * (size / 2.0) - 0.5


def pixels_to_ndc(pixels: torch.Tensor, size: int = CROP_SIZE) -> torch.Tensor:
    """``(..., 2)`` pixel coordinates in a ``size`` crop to normalised coordinates in [-1, 1]."""
    return (pixels + 0.5) * (2.0 / size) - 1.0


def weak_perspective_project(points: torch.Tensor, camera: torch.Tensor) -> torch.Tensor:
    """Project camera-frame points with a weak-perspective camera.

    Args:
        points: ``(B, ..., 3)`` points in metres, rotated into the camera frame (root-relative).
        camera: ``(B, 3)`` ``[s, tx, ty]``; ``s`` in NDC units per metre, ``t`` in metres.

    Returns:
        ``(B, ..., 2)`` normalised image coordinates (``-1 .. 1`` spans the crop).
    """
    scale = camera[:, 0].reshape(-1, *([1] * (points.dim() - 1)))
    shift = camera[:, 1:].reshape(-1, *([1] * (points.dim() - 2)), 2)
    return scale * (points[..., :2] + shift)


def perspective_project(
    points: torch.Tensor, focal_px: float | torch.Tensor = SYNTHETIC_FOCAL_PX, size: int = CROP_SIZE
) -> torch.Tensor:
    """Project camera-frame points (z forward, metres) to pixels of a ``size`` crop.

    Args:
        points: ``(..., 3)``; z must be positive.
        focal_px: focal length in pixels (scalar, or broadcastable to ``points[..., 0]``).

    Returns:
        ``(..., 2)`` pixel coordinates, principal point at the crop centre.
    """
    centre = (size - 1) / 2.0
    inverse_depth = 1.0 / points[..., 2:3]
    focal = torch.as_tensor(focal_px, dtype=points.dtype, device=points.device)
    if focal.dim() > 0:
        focal = focal.unsqueeze(-1)
    return points[..., :2] * inverse_depth * focal + centre

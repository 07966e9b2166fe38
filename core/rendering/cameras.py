"""Random perspective cameras for synthetic training images (paper's supplement table).

The paper gives the camera translation as mean ``(0, -0.2, 2.5)`` m with "var."
``(0.05, 0.05, 0.25)`` m in PyTorch3D's camera frame (x left, y up, z forward), and a 300 px
focal length at 256 px. Our camera frame is OpenCV's (x right, y down, z forward, see
:mod:`hkpd.camera_conventions`): a point ``(x, y, z)`` in PyTorch3D's frame is ``(-x, -y, z)`` in
ours, so the mean becomes ``(0, +0.2, 2.5)`` (the body sits 0.2 m below the optical axis in both
frames).

The table does not say which distribution the spreads belong to. We follow the authors' public
training code (``augment_cam_t``): x and y are Gaussian with standard deviation 0.05 m, and z is
uniform within ±0.25 m of the mean. Both are keyword arguments of :func:`sample_cameras`.
"""

from __future__ import annotations

import torch

from hkpd.camera_conventions import SYNTHETIC_FOCAL_PX

MEAN_TRANSLATION = (0.0, 0.2, 2.5)
"""Mean camera-frame translation of the body, metres, OpenCV axes."""

XY_STD = 0.05
"""Standard deviation of the x and y translation, metres."""

Z_HALF_RANGE = 0.25
"""Half-width of the uniform z translation range, metres."""


def sample_cameras(
    count: int,
    generator: torch.Generator | None = None,
    device: torch.device | str = "cpu",
    mean_translation: tuple[float, float, float] = MEAN_TRANSLATION,
    xy_std: float = XY_STD,
    z_half_range: float = Z_HALF_RANGE,
    focal_px: float = SYNTHETIC_FOCAL_PX,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Random body translations and focal lengths.

    Args:
        count: number of cameras B.
        generator: torch random generator (None: the global one); the numbers are drawn on its
            device and moved to ``device``.
        device: where the tensors live.
        mean_translation, xy_std, z_half_range: translation distribution (module docstring).
        focal_px: focal length in pixels for every camera.

    Returns:
        ``translation (B, 3)`` metres, camera frame (add it to the body's camera-frame
        vertices), and ``focal_px (B,)``, both float32.
    """
    if count < 0:
        raise ValueError(f"count must be non-negative, got {count}")
    draw = generator.device if generator is not None else torch.device(device)
    mean = torch.tensor(mean_translation, dtype=torch.float32, device=draw)
    noise_xy = torch.randn(count, 2, generator=generator, device=draw) * xy_std
    noise_z = (torch.rand(count, 1, generator=generator, device=draw) * 2.0 - 1.0) * z_half_range
    translation = (mean + torch.cat((noise_xy, noise_z), dim=1)).to(device)
    focal = torch.full((count,), float(focal_px), dtype=torch.float32, device=device)
    return translation, focal

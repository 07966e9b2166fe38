"""Axis-aligned maps of pixel coordinates, ``p -> p * scale + shift``, for numpy and torch alike.

Every map between the images of the predictor (the photo as displayed, its downscaled working
copy, the detector's search region, the 256-pixel crop) is a per-axis scale plus a shift, so
one helper serves them all and keeps the array type, dtype and device of its input.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import torch

Points = TypeVar("Points", np.ndarray, torch.Tensor)


def scale_and_shift(points: Points, scale: Sequence[float], shift: Sequence[float]) -> Points:
    """``points * scale + shift`` on the last axis.

    Args:
        points: ``(..., 2)`` pixel coordinates ``(u, v)``; a numpy array (any real dtype; integer
            input gives float64) or a torch tensor (floating; kept on its device).
        scale: ``(2,)`` per-axis factors.
        shift: ``(2,)`` per-axis offsets, in output pixels.

    Returns:
        ``(..., 2)`` of the input's kind.

    Raises:
        ValueError: the last axis is not of size 2.
    """
    if points.shape[-1:] != (2,):
        raise ValueError(f"expected points of shape (..., 2), got {tuple(points.shape)}")
    if isinstance(points, torch.Tensor):
        dtype = points.dtype if points.is_floating_point() else torch.float64
        scale_t = torch.as_tensor(scale, dtype=dtype, device=points.device)
        shift_t = torch.as_tensor(shift, dtype=dtype, device=points.device)
        return points.to(dtype) * scale_t + shift_t
    array = np.asarray(points)
    if not np.issubdtype(array.dtype, np.floating):
        array = array.astype(np.float64)
    return array * np.asarray(scale, dtype=array.dtype) + np.asarray(shift, dtype=array.dtype)

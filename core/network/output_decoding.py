"""Turning raw fully connected outputs into valid distribution and camera parameters.

Every head ends in a linear layer whose raw outputs are decoded here:

- shape: ``mean`` as is, ``std = softplus(raw) + MIN_SHAPE_STD`` (positive);
- global rotation: a 6D vector (two 3-vectors, Zhou et al. 2019) orthonormalised by Gram-Schmidt
  into a rotation matrix;
- camera ``[s, tx, ty]``: ``s = softplus(raw_s)`` (positive), ``t`` as is;
- pose: ``F = raw + c · I`` per joint, with ``c`` the initial concentration; with a
  concentration gain (``NetworkConfig.concentration_gain``) each joint's ``F`` is further scaled
  by ``exp(g)``, ``g`` an extra per-joint output clamped to ``±MAX_LOG_GAIN``.

Decoding always happens in at least float32: under mixed precision (``torch.autocast``) the final
layers' raw outputs are half or bfloat16, but distribution parameters go through SVDs and
normalisers that need full precision.

The ``*_bias`` helpers give the final layers' initial biases so that an untrained network predicts
a sensible starting point: an upright body facing the camera (``FRONTAL_GLOBAL_ORIENT``), a
weak-perspective scale that makes a 1.7 m body span most of the crop, and a broad shape
distribution.
"""

from __future__ import annotations

import math

import roma
import torch
from torch.nn import functional

from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT

MIN_SHAPE_STD = 1e-3
"""Lower bound of the predicted shape standard deviations (keeps the NLL finite)."""

ROTATION_6D = 6
CAMERA_PARAMETERS = 3


def global_size(num_betas: int) -> int:
    """Raw outputs for shape mean and std, 6D global rotation and camera: ``2K + 9``."""
    return 2 * num_betas + ROTATION_6D + CAMERA_PARAMETERS


def inverse_softplus(value: float) -> float:
    """The ``x`` with ``softplus(x) = value`` (value > 0)."""
    return value + math.log(-math.expm1(-value))


def global_bias(num_betas: int, shape_std: float, camera_scale: float) -> torch.Tensor:
    """``(2K + 9,)`` initial bias of the global outputs (see the module docstring)."""
    bias = torch.zeros(global_size(num_betas))
    bias[num_betas : 2 * num_betas] = inverse_softplus(shape_std - MIN_SHAPE_STD)
    frontal_columns = FRONTAL_GLOBAL_ORIENT[:, :2].T.reshape(-1)  # first two columns
    bias[2 * num_betas : 2 * num_betas + ROTATION_6D] = frontal_columns
    bias[2 * num_betas + ROTATION_6D] = inverse_softplus(camera_scale)
    return bias


def full_precision(x: torch.Tensor) -> torch.Tensor:
    """``x`` as float32 if it is half or bfloat16, else unchanged (float64 stays float64)."""
    return x.float() if x.dtype in (torch.float16, torch.bfloat16) else x


def rotation_from_6d(raw: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` two stacked 3-vectors (first and second column) to ``(..., 3, 3)`` rotations."""
    columns = raw.unflatten(-1, (2, 3)).transpose(-1, -2)  # (..., 3, 2)
    return roma.special_gramschmidt(columns, epsilon=1e-6)


def decode_globals(
    raw: torch.Tensor, num_betas: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Split and decode ``(B, 2K + 9)`` raw global outputs.

    Returns:
        ``shape_mean (B, K)``, ``shape_std (B, K)`` (> 0), ``global_orient (B, 3, 3)``,
        ``camera (B, 3)`` as ``[s > 0, tx, ty]``.
    """
    raw = full_precision(raw)
    mean = raw[:, :num_betas]
    std = functional.softplus(raw[:, num_betas : 2 * num_betas]) + MIN_SHAPE_STD
    orient = rotation_from_6d(raw[:, 2 * num_betas : 2 * num_betas + ROTATION_6D])
    cam_raw = raw[:, 2 * num_betas + ROTATION_6D :]
    camera = torch.cat((functional.softplus(cam_raw[:, :1]), cam_raw[:, 1:]), dim=1)
    return mean, std, orient, camera


MAX_LOG_GAIN = 6.0
"""Bound of the log concentration gain: ``exp(±6)`` scales ``F`` by at most ~400 either way."""


class _InwardClamp(torch.autograd.Function):
    """``clamp(value, -bound, bound)`` whose gradient is dropped only where it would push an
    out-of-range value further out.

    A plain clamp has zero gradient beyond its bounds, so a log-gain that one large step threw
    past ``-MAX_LOG_GAIN`` can never come back: the joint's concentration stays at ``exp(-6)``
    of its raw value for good (the orientation fine-tunes lost both elbows, both hands and the
    right collar this way; docs/model_history.md, section 5). Here the gradient still passes when a
    descent step would move the value back towards the range; the forward value is unchanged.
    """

    @staticmethod
    def forward(ctx, value: torch.Tensor, bound: float) -> torch.Tensor:
        ctx.save_for_backward(value)
        ctx.bound = bound
        return value.clamp(-bound, bound)

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> tuple[torch.Tensor, None]:
        (value,) = ctx.saved_tensors
        # a descent step changes value by -grad: below the range only grad < 0 raises it
        outward = ((value < -ctx.bound) & (grad > 0)) | ((value > ctx.bound) & (grad < 0))
        return grad.masked_fill(outward, 0.0), None


def bounded_log_gain(log_gain: torch.Tensor) -> torch.Tensor:
    """``log_gain`` clamped to ``±MAX_LOG_GAIN``, with a gradient that can bring it back
    from beyond the bound (:class:`_InwardClamp`)."""
    return _InwardClamp.apply(log_gain, MAX_LOG_GAIN)


def decode_pose(
    raw: torch.Tensor, concentration: float, log_gain: torch.Tensor | None = None
) -> torch.Tensor:
    """Raw outputs to matrix-Fisher parameters ``exp(g) · (raw + c · I)``.

    Args:
        raw: ``(..., 9)`` raw outputs of one or more joints.
        concentration: ``c``, the initial concentration.
        log_gain: optional ``(...)`` or ``(..., 1)`` log-gains ``g`` (clamped to
            ``±MAX_LOG_GAIN`` by :func:`bounded_log_gain`). Scaling ``F`` keeps the mode and
            principal axes and multiplies every singular value, so one output moves a joint's
            whole concentration; zero (as initialised) leaves ``F`` unchanged.

    Returns:
        ``(..., 3, 3)`` in at least float32.
    """
    raw = full_precision(raw)
    eye = torch.eye(3, dtype=raw.dtype, device=raw.device)
    F = raw.unflatten(-1, (3, 3)) + concentration * eye
    if log_gain is None:
        return F
    gain = bounded_log_gain(full_precision(log_gain).reshape(F.shape[:-2]))
    return F * gain.exp()[..., None, None]

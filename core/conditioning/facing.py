"""The two facings of a start: as the network read it, and turned half about the body's up axis.

A 2D keypoint detector tells a person's left from right, and so whether the person faces the
camera (left shoulder to the right of the right one in the photo, for an upright person) or is
seen from behind. The network, trained almost only on people facing it, may read a person seen
from behind as facing the camera; a fit started there cannot turn the body round against the
global rotation's prior (0.5 rad) and bends the limbs instead (the cook of ``coco_mini``
val2017 ``000000397133.jpg``: an upright man read leaning 34°, arms a zigzag across his back).
So the fit also starts from each start with its global rotation composed with a half turn about
the body's vertical axis, ``R_g' = R_g · diag(-1, 1, -1)`` (SMPL's Y is up, +Z forward): the
same relative pose, shape and camera, the body turned on the spot about its root, and its own
global-rotation prior centred there. The left/right assignment of the keypoints stays, as the
detector made it. Whichever start ends with the lower negative log posterior wins
(:func:`hkpd.conditioning.condition_on_keypoints`; ``docs/evidence.md``, "Facing").
"""

from __future__ import annotations

from dataclasses import replace

import torch

from hkpd.distributions import BodyDistribution

HALF_TURN_ABOUT_UP = torch.tensor([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
"""``(3, 3)`` a half turn about the body frame's up axis (SMPL Y), applied before the global
rotation."""


def half_turned(starts: BodyDistribution) -> BodyDistribution:
    """``starts`` turned 180° about each body's own vertical axis (``R_g · HALF_TURN_ABOUT_UP``);
    pose, shape and camera unchanged."""
    turn = HALF_TURN_ABOUT_UP.to(starts.global_orient)
    return replace(starts, global_orient=starts.global_orient @ turn)


def with_facings(starts: BodyDistribution, facings: int) -> BodyDistribution:
    """The fit's starts: the ``B`` starts as given (``facings`` 1), then (``facings`` 2) their
    half-turned copies: ``(facings · B,)``.

    Raises:
        ValueError: ``facings`` is not 1 or 2.
    """
    if facings == 1:
        return starts
    if facings != 2:
        raise ValueError(f"facings must be 1 (as read) or 2 (also half-turned), got {facings}")
    turned = half_turned(starts).tensors()
    return BodyDistribution(
        *(torch.cat(pair) for pair in zip(starts.tensors(), turned, strict=True))
    )


def faces_camera(global_orient: torch.Tensor) -> torch.Tensor:
    """``(...)`` bool: the body's forward axis (body +Z) points towards the camera, i.e. its
    camera-frame z component (the camera looks along +z) is negative; ``global_orient (..., 3,
    3)`` maps body axes to the camera's."""
    return global_orient[..., 2, 2] < 0

"""How synthetic bodies are turned in the picture: upright, leaning, lying, upside down, seen
from above or below.

The generator already turns every body by a random heading about the vertical and tilts the
camera by up to ±10°, which only ever shows people upright. Real photos do not: in held-out
annotated photos 34 % of people lean or lie more than 60° from upright (0.7 % of the old
training crops leaned more than 30°). An :class:`OrientationMix` adds, on top, a roll of the
whole view about the camera's optical axis (in-plane: leaning, lying sideways in the picture,
inverted) and a steep camera pitch (seen from high above or below; with the heading this also
shows people lying face up, face down or on their side towards the camera).

The *tilt* of an example is the angle between the picture's up direction and the body's
pelvis-to-neck direction as projected into the picture (:func:`image_tilt_degrees`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import roma
import torch


@dataclass(frozen=True)
class OrientationMix:
    """Extra view rotations of synthetic examples.

    Attributes:
        roll_probability: share of examples rolled about the optical axis by an angle uniform
            in ``±max_roll_deg``.
        max_roll_deg: largest roll, degrees (180: any in-plane orientation).
        steep_view_probability: share of examples whose camera is also pitched by an angle
            uniform in ``±max_steep_pitch_deg`` (seen from above or below).
        max_steep_pitch_deg: largest extra pitch, degrees.
    """

    roll_probability: float = 0.0
    max_roll_deg: float = 180.0
    steep_view_probability: float = 0.0
    max_steep_pitch_deg: float = 75.0

    def __post_init__(self) -> None:
        for name in ("roll_probability", "steep_view_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"OrientationMix.{name} must lie in [0, 1]")
        if not 0.0 <= self.max_roll_deg <= 180.0 or not 0.0 <= self.max_steep_pitch_deg <= 90.0:
            raise ValueError("max_roll_deg must lie in [0, 180] and max_steep_pitch_deg in [0, 90]")

    @property
    def is_upright(self) -> bool:
        """True when the mix adds nothing (the paper's upright data)."""
        return self.roll_probability == 0.0 and self.steep_view_probability == 0.0


UPRIGHT = OrientationMix()
"""The paper's data: no extra roll or pitch (draws no random numbers, so the upright fixed test
set is unchanged)."""

TRAINING_MIX = OrientationMix(roll_probability=0.4, steep_view_probability=0.15)
"""hkpd's training mix: 40 % rolled uniformly (about a third of all examples lean more than 30°
in the picture), 15 % seen steeply from above or below."""

ANY_ORIENTATION = OrientationMix(roll_probability=1.0, steep_view_probability=0.3)
"""The any-orientation test split: every example rolled uniformly, 30 % seen steeply."""


def sample_view_rotation(
    count: int, generator: torch.Generator, mix: OrientationMix
) -> torch.Tensor | None:
    """``(count, 3, 3)`` camera-frame rotations to apply on the left of ``global_orient``, or
    None for :data:`UPRIGHT` (no random numbers are drawn then)."""
    if mix.is_upright:
        return None
    rolled = torch.rand(count, generator=generator) < mix.roll_probability
    roll = (torch.rand(count, generator=generator) * 2 - 1) * math.radians(mix.max_roll_deg)
    steep = torch.rand(count, generator=generator) < mix.steep_view_probability
    pitch = (torch.rand(count, generator=generator) * 2 - 1) * math.radians(mix.max_steep_pitch_deg)
    zeros = torch.zeros(count)
    roll = torch.where(rolled, roll, zeros)
    pitch = torch.where(steep, pitch, zeros)
    about_axis = roma.rotvec_to_rotmat(torch.stack([zeros, zeros, roll], -1))
    from_above = roma.rotvec_to_rotmat(torch.stack([pitch, zeros, zeros], -1))
    return about_axis @ from_above


def image_tilt_degrees(keypoints2d: torch.Tensor) -> torch.Tensor:
    """``(B,)`` tilt in degrees (0 upright, 180 upside down) of COCO keypoints ``(B, 17, 2)``.

    Measured from the hips' midpoint to the shoulders' midpoint, against the picture's up
    (``-v``).
    """
    shoulders = keypoints2d[:, [5, 6]].mean(1)
    hips = keypoints2d[:, [11, 12]].mean(1)
    direction = shoulders - hips
    return torch.rad2deg(torch.atan2(direction[:, 0], -direction[:, 1]).abs())

"""A procedural pose prior: random joint rotations inside anatomical limits, so the synthetic
data flow runs without any motion-capture files.

Each body joint's relative rotation is built from three intrinsic Euler angles in SMPL axes
(joint frames are parallel to the SMPL axes in the T-pose rest: X to the body's left, Y up,
Z forward). :data:`JOINT_LIMITS` lists, per joint, the Euler order and the allowed range of each
angle in degrees; the signs encode the direction of bending, e.g. knees flex only by +X (shin
backwards), the left elbow only by -Y and the right elbow only by +Y (forearm forwards).

Sampling: for each pose a "spread" ``s ~ U(0, 1)`` is drawn, and each angle is
``neutral + s * (u - neutral)`` with ``u`` uniform in the joint's range, which stays inside the
range because it is a convex combination of two points of it. Small spreads give poses close
to the neutral stance (arms hanging, knees nearly straight), large ones span the whole range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import roma
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES


@dataclass(frozen=True)
class JointLimit:
    """Euler-angle limits of one joint.

    Attributes:
        order: intrinsic Euler order for ``roma.euler_to_rotmat`` (e.g. ``"XYZ"`` means
            ``R = Rx @ Ry @ Rz``); the middle angle's range always lies within (-90, 90) degrees
            so that the angles can be read back uniquely.
        ranges: ``(low, high)`` in degrees for each angle, in ``order``'s order.
        neutral: the angles of the neutral stance, inside the ranges.
    """

    order: str
    ranges: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
    neutral: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _limit(order: str, a: tuple, b: tuple, c: tuple, neutral=(0.0, 0.0, 0.0)) -> JointLimit:
    return JointLimit(order, (a, b, c), neutral)


_SPINE = _limit("XYZ", (-15, 30), (-15, 15), (-12, 12))

JOINT_LIMITS: dict[str, JointLimit] = {
    # Hips: X = flexion (negative swings the thigh forward), Y = twist, Z = abduction.
    "left_hip": _limit("XYZ", (-110, 25), (-30, 30), (-15, 45)),
    "right_hip": _limit("XYZ", (-110, 25), (-30, 30), (-45, 15)),
    "spine1": _SPINE,
    # Knees bend one way only: +X moves the shin backwards.
    "left_knee": _limit("XYZ", (0, 140), (-5, 5), (-3, 3), (5, 0, 0)),
    "right_knee": _limit("XYZ", (0, 140), (-5, 5), (-3, 3), (5, 0, 0)),
    "spine2": _SPINE,
    # Ankles: +X points the toes down (plantar flexion).
    "left_ankle": _limit("XYZ", (-25, 45), (-15, 15), (-15, 15)),
    "right_ankle": _limit("XYZ", (-25, 45), (-15, 15), (-15, 15)),
    "spine3": _SPINE,
    "left_foot": _limit("XYZ", (-30, 10), (-5, 5), (-5, 5)),
    "right_foot": _limit("XYZ", (-30, 10), (-5, 5), (-5, 5)),
    "neck": _limit("XYZ", (-25, 35), (-35, 35), (-20, 20)),
    # Collars: Z raises (shrugs) the shoulder, Y pulls it forwards/backwards.
    "left_collar": _limit("ZYX", (-10, 20), (-15, 15), (-5, 5)),
    "right_collar": _limit("ZYX", (-20, 10), (-15, 15), (-5, 5)),
    "head": _limit("XYZ", (-25, 25), (-35, 35), (-15, 15)),
    # Shoulders: Z lowers/raises the arm in the frontal plane (arm hanging = -/+ 65..85),
    # Y swings it forwards (negative on the left, positive on the right), X twists it.
    "left_shoulder": _limit("ZYX", (-85, 45), (-85, 40), (-45, 45), (-65, 0, 0)),
    "right_shoulder": _limit("ZYX", (-45, 85), (-40, 85), (-45, 45), (65, 0, 0)),
    # Elbows bend one way only: the forearm folds forwards.
    "left_elbow": _limit("YXZ", (-145, 0), (-40, 40), (-5, 5), (-15, 0, 0)),
    "right_elbow": _limit("YXZ", (0, 145), (-40, 40), (-5, 5), (15, 0, 0)),
    # Wrists: Z flexes the hand up/down, Y sideways, X twists.
    "left_wrist": _limit("ZYX", (-60, 60), (-25, 25), (-30, 30)),
    "right_wrist": _limit("ZYX", (-60, 60), (-25, 25), (-30, 30)),
    "left_hand": _limit("ZYX", (-10, 10), (-5, 5), (-5, 5)),
    "right_hand": _limit("ZYX", (-10, 10), (-5, 5), (-5, 5)),
}
"""Anatomical limits of the 23 body joints (degrees, SMPL axes)."""


class ProceduralPosePrior:
    """Random anatomically limited poses; implements :class:`hkpd.poses.PoseSource`.

    Args:
        max_tilt_deg: largest tilt of the body away from upright (the tilt angle is drawn from
            a normal with standard deviation ``max_tilt_deg / 2``, clipped).
        limits: per-joint limits; default :data:`JOINT_LIMITS`.
    """

    def __init__(
        self, max_tilt_deg: float = 15.0, limits: dict[str, JointLimit] | None = None
    ) -> None:
        limits = JOINT_LIMITS if limits is None else limits
        missing = [n for n in BODY_JOINT_NAMES if n not in limits]
        if missing:
            raise ValueError(f"limits lack body joints {missing}")
        if not 0 <= max_tilt_deg <= 90:
            raise ValueError(f"max_tilt_deg must be in [0, 90], got {max_tilt_deg}")
        self.max_tilt_deg = float(max_tilt_deg)
        self.limits = {n: limits[n] for n in BODY_JOINT_NAMES}
        self._low = torch.tensor([[r[0] for r in lim.ranges] for lim in self.limits.values()])
        self._high = torch.tensor([[r[1] for r in lim.ranges] for lim in self.limits.values()])
        self._neutral = torch.tensor([lim.neutral for lim in self.limits.values()])
        self._joints_by_order: dict[str, list[int]] = {}
        for joint, limit in enumerate(self.limits.values()):
            self._joints_by_order.setdefault(limit.order, []).append(joint)
        grouped_joints = [j for joints in self._joints_by_order.values() for j in joints]
        self._ungroup = torch.argsort(torch.tensor(grouped_joints))
        if ((self._neutral < self._low) | (self._neutral > self._high)).any():
            raise ValueError("every neutral angle must lie inside its range")

    def sample_angles(self, count: int, generator: torch.Generator) -> torch.Tensor:
        """Euler angles of ``count`` random poses.

        Returns:
            ``(count, 23, 3)`` float32 degrees, each joint in its own Euler order.
        """
        spread = torch.rand(count, 1, 1, generator=generator)
        uniform = torch.rand(count, 23, 3, generator=generator)
        target = self._low + uniform * (self._high - self._low)
        angles = self._neutral + spread * (target - self._neutral)
        return torch.minimum(torch.maximum(angles, self._low), self._high)

    def sample(self, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """Draw ``count`` poses.

        Returns:
            ``body_pose (count, 23, 3, 3)`` relative rotations and ``global_orient (count, 3, 3)``
            (upright up to a small tilt, uniformly random heading about the vertical Y axis),
            float32, SMPL axes.
        """
        if count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        angles = self.sample_angles(count, generator)
        # One conversion per Euler order, then back to joint order (index_select is much
        # faster than assigning into a list of joint indices).
        grouped = torch.cat(
            [
                roma.euler_to_rotmat(order, angles[:, joints], degrees=True)
                for order, joints in self._joints_by_order.items()
            ],
            dim=1,
        )
        body_pose = grouped.index_select(1, self._ungroup)
        yaw = 2 * math.pi * torch.rand(count, generator=generator)
        tilt_direction = 2 * math.pi * torch.rand(count, generator=generator)
        tilt = torch.randn(count, generator=generator) * math.radians(self.max_tilt_deg) / 2
        tilt = tilt.clamp(-math.radians(self.max_tilt_deg), math.radians(self.max_tilt_deg))
        zero = torch.zeros(count)
        heading = roma.rotvec_to_rotmat(torch.stack([zero, yaw, zero], dim=-1))
        tilt_axis = torch.stack([torch.cos(tilt_direction), zero, torch.sin(tilt_direction)], -1)
        lean = roma.rotvec_to_rotmat(tilt_axis * tilt[:, None])
        return body_pose, lean @ heading

    def __repr__(self) -> str:
        return f"ProceduralPosePrior(max_tilt_deg={self.max_tilt_deg})"

"""Pose families the mocap bank lacks: sitting, kneeling, lunging, squatting, arms overhead,
reaching, a leg raised, lying relaxed.

The CMU subset is mostly walking and running, so a kneeling lunge reads as a stride. Each
:class:`PoseFamily` fixes the angles of the joints that define it (a target and a uniform
jitter, in the conventions of :data:`hkpd.poses.procedural.JOINT_LIMITS`, expressed per limb
role: *front* and *back* leg, *raised* and *other* arm, swapped left/right at random), and
draws every other joint from the procedural prior with a small spread. All angles are clipped
to the joint limits, so poses stay anatomically plausible (shoulders may rise to 90° above the
horizontal here, for arms overhead). Lying people come from these poses combined with the
orientation mix (:mod:`hkpd.synthesis.orientation`), which rolls the view.

Angle conventions by role (degrees): hip ``flex`` (thigh forwards), ``abduct`` (outwards);
knee ``bend``; shoulder ``raise`` (0: arm horizontal sideways, -65: hanging, 90: overhead) and
``forward`` (swing forwards); elbow ``bend``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import roma
import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses.procedural import JOINT_LIMITS, JointLimit, ProceduralPosePrior

Range = tuple[float, float]


@dataclass(frozen=True)
class PoseFamily:
    """One family: per role, ``(low, high)`` degree ranges of the defining angles.

    Attributes:
        name: e.g. ``"kneeling lunge"``.
        front_leg, back_leg: ``{"flex": (lo, hi), "abduct": ..., "bend": ...}``.
        raised_arm, other_arm: ``{"raise": ..., "forward": ..., "bend": ...}``.
        spine_flex: forward bend of each of the three spine joints.
    """

    name: str
    front_leg: dict[str, Range] = field(default_factory=dict)
    back_leg: dict[str, Range] = field(default_factory=dict)
    raised_arm: dict[str, Range] = field(default_factory=dict)
    other_arm: dict[str, Range] = field(default_factory=dict)
    spine_flex: Range | None = None


FAMILIES: tuple[PoseFamily, ...] = (
    PoseFamily("sitting", {"flex": (80, 100), "bend": (75, 105)},
               {"flex": (80, 100), "bend": (75, 105)}, spine_flex=(-5, 12)),
    PoseFamily("kneeling upright", {"flex": (-10, 15), "bend": (85, 120)},
               {"flex": (-10, 15), "bend": (85, 120)}),
    PoseFamily("kneeling lunge", {"flex": (70, 100), "bend": (75, 105)},
               {"flex": (-20, 5), "bend": (80, 115)}),
    PoseFamily("standing lunge", {"flex": (45, 80), "bend": (45, 95)},
               {"flex": (-25, -10), "abduct": (0, 15), "bend": (0, 15)}),
    PoseFamily("squat", {"flex": (95, 110), "abduct": (5, 30), "bend": (110, 140)},
               {"flex": (95, 110), "abduct": (5, 30), "bend": (110, 140)},
               spine_flex=(10, 28)),
    PoseFamily("arms overhead", raised_arm={"raise": (60, 90), "forward": (-10, 20)},
               other_arm={"raise": (60, 90), "forward": (-10, 20)}),
    PoseFamily("reaching", raised_arm={"raise": (-20, 40), "forward": (50, 85), "bend": (0, 30)}),
    PoseFamily("arms out", raised_arm={"raise": (-15, 20), "forward": (-15, 20)},
               other_arm={"raise": (-15, 20), "forward": (-15, 20)}),
    PoseFamily("leg raised", {"flex": (50, 105), "abduct": (0, 30), "bend": (0, 90)},
               {"flex": (-10, 10), "bend": (0, 10)}),
    PoseFamily("lying relaxed", {"flex": (-5, 40), "bend": (0, 60)},
               {"flex": (-5, 40), "bend": (0, 60)},
               {"raise": (-70, 90)}, {"raise": (-70, 90)}),
)  # fmt: skip
"""The families, drawn with equal probability."""

WIDER_LIMITS: dict[str, JointLimit] = {
    **JOINT_LIMITS,
    "left_shoulder": JointLimit("ZYX", ((-85, 90), (-85, 40), (-45, 45)), (-65, 0, 0)),
    "right_shoulder": JointLimit("ZYX", ((-90, 85), (-40, 85), (-45, 45)), (65, 0, 0)),
}
"""The procedural limits with shoulders that reach overhead (90° above the horizontal)."""

# (joint, Euler slot, sign) per role angle, for the left side; the right side flips the sign
# of the slots that mirror (abduction, the shoulder's raise and swing, the elbow's bend).
_LEG = {"flex": ("hip", 0, -1.0, False), "abduct": ("hip", 2, 1.0, True),
        "bend": ("knee", 0, 1.0, False)}  # fmt: skip
_ARM = {"raise": ("shoulder", 0, 1.0, True), "forward": ("shoulder", 1, -1.0, True),
        "bend": ("elbow", 0, -1.0, True)}  # fmt: skip
_SPINES = ("spine1", "spine2", "spine3")


class PoseArchetypes:
    """Poses of the :data:`FAMILIES`; implements :class:`hkpd.poses.PoseSource`.

    Args:
        background_spread: spread of the procedural prior for the joints a family leaves free
            (0: neutral stance, 1: anywhere in the limits).
        max_tilt_deg: the body's lean from upright (the orientation mix adds the rest).
    """

    def __init__(self, background_spread: float = 0.35, max_tilt_deg: float = 10.0) -> None:
        self.background = ProceduralPosePrior(max_tilt_deg=max_tilt_deg, limits=WIDER_LIMITS)
        self.background_spread = float(background_spread)
        self._index = {name: i for i, name in enumerate(BODY_JOINT_NAMES)}

    def family_of(self, count: int, generator: torch.Generator) -> torch.Tensor:
        """``(count,)`` family indices, uniform."""
        return torch.randint(len(FAMILIES), (count,), generator=generator)

    def sample_angles(
        self, count: int, generator: torch.Generator
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Euler angles ``(count, 23, 3)`` (degrees, per-joint orders) and the family index."""
        prior = self.background
        uniform = torch.rand(count, 23, 3, generator=generator)
        target = prior._low + uniform * (prior._high - prior._low)
        angles = prior._neutral + self.background_spread * (target - prior._neutral)
        family = self.family_of(count, generator)
        mirrored = torch.rand(count, generator=generator) < 0.5
        draws = torch.rand(count, 16, generator=generator)
        for item in range(count):
            spec = FAMILIES[int(family[item])]
            sides = ("right", "left") if bool(mirrored[item]) else ("left", "right")
            column = iter(range(16))
            roles = (
                (_LEG, spec.front_leg, sides[0]),
                (_LEG, spec.back_leg, sides[1]),
                (_ARM, spec.raised_arm, sides[0]),
                (_ARM, spec.other_arm, sides[1]),
            )
            for table, ranges, side in roles:
                for role, (low, high) in ranges.items():
                    part, slot, sign, mirrors = table[role]
                    value = low + (high - low) * float(draws[item, next(column)])
                    if side == "right" and mirrors:
                        sign = -sign
                    angles[item, self._index[f"{side}_{part}"], slot] = sign * value
            if spec.spine_flex is not None:
                low, high = spec.spine_flex
                bend = low + (high - low) * float(draws[item, 15])
                for spine in _SPINES:
                    angles[item, self._index[spine], 0] = bend / 3.0
        clipped = torch.minimum(torch.maximum(angles, prior._low), prior._high)
        return clipped, family

    def sample(self, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """``body_pose (count, 23, 3, 3)`` and ``global_orient (count, 3, 3)`` (upright up to
        ``max_tilt_deg``, random heading), float32, SMPL axes."""
        if count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        angles, _ = self.sample_angles(count, generator)
        prior = self.background
        grouped = torch.cat(
            [roma.euler_to_rotmat(order, angles[:, joints], degrees=True)
             for order, joints in prior._joints_by_order.items()], dim=1,
        )  # fmt: skip
        body_pose = grouped.index_select(1, prior._ungroup)
        yaw = 2 * math.pi * torch.rand(count, generator=generator)
        zero = torch.zeros(count)
        heading = roma.rotvec_to_rotmat(torch.stack([zero, yaw, zero], dim=-1))
        return body_pose, heading

    def __repr__(self) -> str:
        return f"PoseArchetypes({len(FAMILIES)} families)"

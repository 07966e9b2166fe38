"""A pose source that mixes the mocap bank with pose families and limb-swapped mocap poses.

:class:`PoseMix` says the shares: a pose comes from the bank, from
:class:`hkpd.poses.archetypes.PoseArchetypes` (sitting, kneeling, lunging, ...), or is a
*limb mix*: the upper body of one bank pose on the legs of another (the mocap's walking legs
under its reaching arms, and so on), which multiplies the bank's combinations without leaving
the space of recorded joint angles. The bank already holds every pose mirrored.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.poses.archetypes import PoseArchetypes
from hkpd.poses.source import PoseSource

LEG_JOINTS = tuple(
    i for i, name in enumerate(BODY_JOINT_NAMES) if name.split("_")[-1] in
    ("hip", "knee", "ankle", "foot")
)  # fmt: skip
"""Body joints of the legs (taken from the second pose of a limb mix)."""


@dataclass(frozen=True)
class PoseMix:
    """Shares of the pose kinds (the rest comes from the base source).

    Attributes:
        archetype_share: share of :class:`PoseArchetypes` poses.
        limb_mix_share: share of limb-mixed base poses.
    """

    archetype_share: float = 0.0
    limb_mix_share: float = 0.0

    def __post_init__(self) -> None:
        shares = (self.archetype_share, self.limb_mix_share)
        if min(shares) < 0 or sum(shares) > 1:
            raise ValueError(
                f"pose shares must be >= 0 and sum to at most 1, got archetypes "
                f"{self.archetype_share} and limb mixes {self.limb_mix_share}"
            )

    @property
    def is_plain(self) -> bool:
        return self.archetype_share == 0 and self.limb_mix_share == 0


class MixedPoseSource:
    """Base poses, pose families and limb mixes; implements :class:`PoseSource`.

    Args:
        base: the bank (or the procedural prior).
        mix: the shares.
    """

    def __init__(self, base: PoseSource, mix: PoseMix) -> None:
        self.base = base
        self.mix = mix
        self.archetypes = PoseArchetypes()

    def sample(self, count: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """``body_pose (count, 23, 3, 3)`` and ``global_orient (count, 3, 3)``, float32."""
        body_pose, orient = self.base.sample(count, generator)
        body_pose, orient = body_pose.clone(), orient.clone()
        kind = torch.rand(count, generator=generator)
        families = kind < self.mix.archetype_share
        mixed = (~families) & (kind < self.mix.archetype_share + self.mix.limb_mix_share)
        if families.any():
            poses, orients = self.archetypes.sample(int(families.sum()), generator)
            body_pose[families], orient[families] = poses, orients
        if mixed.any():
            legs, _ = self.base.sample(int(mixed.sum()), generator)
            legs_index = torch.tensor(LEG_JOINTS)
            rows = mixed.nonzero().flatten()
            body_pose[rows[:, None], legs_index] = legs[:, legs_index]
        return body_pose, orient

    def __repr__(self) -> str:
        return f"MixedPoseSource({self.base!r}, {self.mix})"

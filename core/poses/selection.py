"""Pick the pose source a command line asked for: a pose bank split, or the procedural prior."""

from __future__ import annotations

from pathlib import Path

from hkpd.poses.bank import PoseBank
from hkpd.poses.mixed_source import MixedPoseSource, PoseMix
from hkpd.poses.procedural import ProceduralPosePrior
from hkpd.poses.source import PoseSource


def pose_source(
    bank: str | Path | None, split: str = "train", mix: PoseMix | None = None
) -> PoseSource:
    """``PoseBank.load(bank, split)``, or a :class:`ProceduralPosePrior` when ``bank`` is None;
    wrapped in a :class:`MixedPoseSource` when ``mix`` adds pose families or limb mixes.

    Raises:
        FileNotFoundError: the bank file is missing (the message says how to build one, or to
            leave the bank out to use the procedural prior).
        ValueError: not a pose bank, or an unknown or empty split.
    """
    base = ProceduralPosePrior() if bank is None else PoseBank.load(bank, split=split)
    if mix is None or mix.is_plain:
        return base
    return MixedPoseSource(base, mix)

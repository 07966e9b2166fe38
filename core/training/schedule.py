"""Loss weights and the staged schedule of the paper's training (Section 4, "Training details").

The paper trains in three stages: (1) the NLLs, the global-rotation loss and the 2D joint loss on
the *mode* only; (2) adding the 2D joint loss on *samples*; (3) adding a 3D joint loss on the
mode. :func:`paper_schedule` builds that schedule with stage boundaries in optimiser steps, and
:meth:`LossSchedule.weights_at` gives the weights that are active at a step.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from itertools import pairwise
from typing import Any

LOSS_TERMS = (
    "shape_nll",
    "pose_nll",
    "global_rotation",
    "joints2d_mode",
    "joints2d_samples",
    "joints3d_mode",
    "shape_tpose_vertices",
)
"""Names of the loss terms, as keys of :func:`hkpd.training.losses.compute_losses`' result."""


@dataclass(frozen=True)
class LossWeights:
    """Weight of each loss term (0 switches a term off and skips its computation).

    The defaults balance the terms' typical magnitudes with the normalisations of
    :mod:`hkpd.training.losses` (NLLs summed over joints/coefficients; squared 2D errors in NDC
    units, where 5 px at 256 px is 0.0015; squared 3D errors in m², where 5 cm is 0.0025). They
    are a starting point, not tuned values; see ``docs/network.md``.

    Attributes:
        shape_nll: Gaussian shape NLL (paper Eq. 7).
        pose_nll: matrix-Fisher NLL of the relative joint rotations (Eq. 8).
        global_rotation: squared Frobenius distance of the global rotation.
        joints2d_mode: 2D COCO keypoint loss of the mode body.
        joints2d_samples: 2D keypoint loss of sampled bodies (Eq. 10).
        joints3d_mode: 3D joint loss of the mode body.
        shape_tpose_vertices: per-vertex T-pose loss of the shape mean (the paper's code adds
            it to the shape NLL): squared vertex distances in m², so each coefficient counts by
            how much it moves the body. Off by default (the shipped runs did without).
    """

    shape_nll: float = 1.0
    pose_nll: float = 1.0
    global_rotation: float = 100.0
    joints2d_mode: float = 1000.0
    joints2d_samples: float = 1000.0
    joints3d_mode: float = 1000.0
    shape_tpose_vertices: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not value >= 0.0:  # also rejects NaN
                raise ValueError(f"loss weight {f.name} must be >= 0, got {value}")

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    def active(self) -> tuple[str, ...]:
        """Names of the terms with a non-zero weight."""
        return tuple(name for name in LOSS_TERMS if getattr(self, name) > 0.0)


@dataclass(frozen=True)
class LossStage:
    """Weights that apply from ``start_step`` until the next stage starts.

    Attributes:
        start_step: first optimiser step (0-based) of the stage.
        weights: the stage's :class:`LossWeights`.
        name: for logs.
    """

    start_step: int
    weights: LossWeights
    name: str = ""


@dataclass(frozen=True)
class LossSchedule:
    """Piecewise-constant loss weights over training steps.

    Args:
        stages: stages with strictly increasing ``start_step``, the first starting at 0.
    """

    stages: tuple[LossStage, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "stages", tuple(self.stages))
        if not self.stages or self.stages[0].start_step != 0:
            raise ValueError("a loss schedule needs at least one stage, the first at step 0")
        starts = [stage.start_step for stage in self.stages]
        if any(b <= a for a, b in pairwise(starts)):
            raise ValueError(f"stage start steps must increase strictly, got {starts}")

    def stage_index(self, step: int) -> int:
        """Index of the stage active at ``step`` (>= 0)."""
        if step < 0:
            raise ValueError(f"step must be >= 0, got {step}")
        index = 0
        for i, stage in enumerate(self.stages):
            if stage.start_step <= step:
                index = i
        return index

    def stage_at(self, step: int) -> LossStage:
        """The :class:`LossStage` active at ``step``."""
        return self.stages[self.stage_index(step)]

    def weights_at(self, step: int) -> LossWeights:
        """The :class:`LossWeights` active at ``step``."""
        return self.stage_at(step).weights

    def to_dict(self) -> dict[str, Any]:
        """Plain data for checkpoints and logs (inverse of :meth:`from_dict`)."""
        return {
            "stages": [
                {"start_step": s.start_step, "name": s.name, "weights": s.weights.to_dict()}
                for s in self.stages
            ]
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LossSchedule:
        return cls(
            tuple(
                LossStage(int(s["start_step"]), LossWeights(**s["weights"]), s.get("name", ""))
                for s in data["stages"]
            )
        )


def paper_schedule(
    samples_start: int, joints3d_start: int, weights: LossWeights | None = None
) -> LossSchedule:
    """The paper's three stages with the given boundaries (in optimiser steps).

    1. from step 0: shape and pose NLL, global rotation, 2D joints of the mode;
    2. from ``samples_start``: plus the 2D joint loss on samples;
    3. from ``joints3d_start``: plus the 3D joint loss on the mode.

    The paper trains 150 epochs with boundaries at epochs 50 and 100. ``weights`` gives the
    weight of every term once it is on (default :class:`LossWeights`).

    Raises:
        ValueError: unless ``0 < samples_start < joints3d_start``.
    """
    if not 0 < samples_start < joints3d_start:
        raise ValueError(
            f"need 0 < samples_start < joints3d_start, got {samples_start} and {joints3d_start}"
        )
    full = LossWeights() if weights is None else weights
    stage1 = replace(full, joints2d_samples=0.0, joints3d_mode=0.0)
    stage2 = replace(full, joints3d_mode=0.0)
    return LossSchedule(
        (
            LossStage(0, stage1, "nll+global+2d-mode"),
            LossStage(samples_start, stage2, "+2d-samples"),
            LossStage(joints3d_start, full, "+3d-joints"),
        )
    )


def paper_schedule_for(total_steps: int, weights: LossWeights | None = None) -> LossSchedule:
    """:func:`paper_schedule` with the paper's proportions: stages at 1/3 and 2/3 of training."""
    if total_steps < 3:
        raise ValueError(f"total_steps must be at least 3, got {total_steps}")
    return paper_schedule(total_steps // 3, 2 * total_steps // 3, weights)

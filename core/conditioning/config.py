"""``EvidenceConfig``: the few numbers that set how strongly 2D keypoints update the prior."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class EvidenceConfig:
    """Settings of the keypoint-evidence posterior (``docs/evidence.md`` says how each was chosen).

    Attributes:
        prior_weight: temperature ``w`` on the network's log-density: the posterior is
            ``p_net(pose, shape)^w × L(keypoints | body)``. Below 1 the network's
            (over-confident) distribution counts for less than its face value.
        keypoint_sigma: standard deviation of one detected keypoint coordinate about the body
            model's keypoint, as a fraction of the crop's side (the crop is 1.2× the person's
            extent, so 0.03 is about 3.6 % of the person's height).
        robust_scale: the Cauchy loss turns from quadratic to logarithmic at this many sigmas,
            so a keypoint the detector put on the wrong limb pulls only weakly.
        min_keypoints: with fewer evidence keypoints the fit is not attempted (the network's
            own distribution is returned, with the reason).
        global_rotation_sigma: radians; weak prior that keeps the global rotation near its
            start (the network predicts a point, not a distribution, for it).
        camera_sigma: weak prior on the camera's log scale and translation (metres) about the
            start's.
        max_iterations: Levenberg-Marquardt iterations at most.
        tolerance: stop when an accepted step lowers the cost by less than this fraction.
        joint_spread: ``"conditional"`` (the default) gives each joint its precision given the
            other joints (the diagonal blocks of the posterior precision: the best independent
            approximation in the mode-seeking sense, every sample consistent with the evidence);
            ``"marginal"`` its marginal precision (evidence shared along a chain counted once
            per chain, but samples drawn joint by joint then scatter the limb ends).
            ``docs/evidence.md`` says how the defaults were chosen.
    """

    prior_weight: float = 0.5
    keypoint_sigma: float = 0.03
    robust_scale: float = 3.0
    min_keypoints: int = 4
    global_rotation_sigma: float = 0.5
    camera_sigma: float = 0.5
    max_iterations: int = 30
    tolerance: float = 1e-6
    joint_spread: str = "conditional"

    def __post_init__(self) -> None:
        positive = {
            "prior_weight": self.prior_weight,
            "keypoint_sigma": self.keypoint_sigma,
            "robust_scale": self.robust_scale,
            "global_rotation_sigma": self.global_rotation_sigma,
            "camera_sigma": self.camera_sigma,
            "tolerance": self.tolerance,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"EvidenceConfig.{name} must be a positive number, got {value}")
        if self.joint_spread not in ("marginal", "conditional"):
            raise ValueError(
                f"EvidenceConfig.joint_spread must be 'marginal' or 'conditional', got "
                f"{self.joint_spread!r}"
            )
        if self.min_keypoints < 1 or self.max_iterations < 1:
            raise ValueError("EvidenceConfig.min_keypoints and max_iterations must be >= 1")

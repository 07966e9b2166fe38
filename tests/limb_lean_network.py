"""A stand-in network that reads a person's lean from its limbs alone (for tests of the upright
reading when no torso is observed)."""

from __future__ import annotations

import math

import torch

from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT
from hkpd.distributions import BodyDistribution
from hkpd.network import NetworkConfig
from hkpd.proxy import NUM_KEYPOINTS
from hkpd.proxy.heatmaps import heatmap_peaks

UPPER_LIMBS = (7, 8, 9, 10)
"""COCO elbows and wrists."""
FEET = (15, 16)
"""COCO ankles."""


def rolled_frontal(degrees: float) -> torch.Tensor:
    """``(3, 3)``: an upright body facing the camera, turned clockwise on screen by ``degrees``."""
    angle = math.radians(degrees)
    roll = torch.eye(3)
    roll[:2, :2] = torch.tensor(
        [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    )
    return roll @ FRONTAL_GLOBAL_ORIENT


class LimbLeanNetwork(torch.nn.Module):
    """Answers a body in the rest pose, facing the camera and leaning as the line from the
    ankles' heatmap peaks to the elbows' and wrists' leans in its input, when that lean is
    within ``reads_within_degrees`` of upright; beyond it, upright (as a network that never
    learnt leaning people). ``leans`` records each lean shown (degrees), ``answers`` each answer.
    """

    def __init__(self, image_size: int, reads_within_degrees: float = 180.0) -> None:
        super().__init__()
        self.config = NetworkConfig(backbone_base_width=8, image_size=image_size)
        self.reads_within_degrees = reads_within_degrees
        self.leans: list[list[float]] = []
        self.answers: list[list[float]] = []

    def forward(self, proxy: torch.Tensor) -> BodyDistribution:
        points, _ = heatmap_peaks(proxy[:, proxy.shape[1] - NUM_KEYPOINTS :])
        direction = points[:, list(UPPER_LIMBS)].mean(1) - points[:, list(FEET)].mean(1)
        leans = [math.degrees(math.atan2(float(du), -float(dv))) for du, dv in direction]
        self.leans.append(leans)
        answers = [lean if abs(lean) <= self.reads_within_degrees else 0.0 for lean in leans]
        self.answers.append(answers)
        count = proxy.shape[0]
        return BodyDistribution(
            F=torch.eye(3).expand(count, 23, 3, 3) * 1000.0,
            shape_mean=torch.zeros(count, 10),
            shape_std=torch.ones(count, 10),
            global_orient=torch.stack([rolled_frontal(answer) for answer in answers]),
            camera=torch.tensor([1.0, 0.0, 0.0]).expand(count, 3).clone(),
        )

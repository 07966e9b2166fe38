"""``KeypointTerm``: the reprojection of the body's COCO keypoints onto the detected ones.

``r_k = (π(X_k) - y_k) / σ_kp`` in crop NDC (two components per keypoint), for evidence
keypoints only (zero elsewhere), robustified per keypoint by the Cauchy loss at
``EvidenceConfig.robust_scale`` sigmas, so a keypoint the detector put on the wrong limb pulls
only weakly.
"""

from __future__ import annotations

import torch

from hkpd.camera_conventions import pixels_to_ndc
from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.evidence_term import PosedBodies
from hkpd.conditioning.keypoint_evidence import KeypointEvidence

NUM_KEYPOINTS = 17


class KeypointTerm:
    """The keypoint evidence as an :class:`~hkpd.conditioning.EvidenceTerm`.

    Args:
        evidence: the observed keypoints in the network's crop.
        config: the keypoint sigma (fraction of the crop side) and the robust scale.
    """

    name = "keypoints"
    residual_shape = (NUM_KEYPOINTS, 2)
    needs_vertices = False
    surface_vertices = None

    def __init__(self, evidence: KeypointEvidence, config: EvidenceConfig) -> None:
        dtype = torch.float64
        self.robust_scale: float | None = config.robust_scale
        self.targets = pixels_to_ndc(evidence.keypoints.to(dtype), evidence.crop_size)  # (17, 2)
        self.observed = evidence.observed.to(dtype)  # (17,)
        self.sigma_ndc = 2.0 * config.keypoint_sigma  # NDC spans 2 per crop side

    def residuals(self, posed: PosedBodies) -> torch.Tensor:
        """``(N, B, 17, 2)`` reprojection residuals in sigmas (zero where no evidence)."""
        ndc = posed.project(posed.keypoints)
        return (ndc - self.targets) / self.sigma_ndc * self.observed[:, None]

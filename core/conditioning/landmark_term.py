"""``LandmarkTerm``: the reprojection of the body's hand and foot landmarks onto the detected ones.

BlazePose's knuckles, thumbs, heels and toes (:mod:`hkpd.body.extremity_landmarks`) are the
only points on the photo that say how a hand or a foot is turned: the wrist and ankle keypoints
sit on the rotation's centre. The term is the keypoint term's form on those landmarks,
``r_l = (π(X_l) - y_l) / σ_l`` in crop NDC (two components per landmark, zero where the photo
shows none: not confident, or under an occluder), robustified per landmark by the Cauchy loss.
``X_l`` is a small vertex regressor on the posed mesh, read through the fit's few posed
surface vertices (``surface_vertices``: a few hundred, not the mesh).

Its own sigmas (:class:`LandmarkConfig`): the keypoint sigma scaled per group (hands, feet),
so that a knuckle whose place on the hand is vaguer than an elbow's on the arm pulls less
(``docs/evidence.md``, "Hand and foot landmarks").
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from hkpd.body.extremity_landmarks import ExtremityLandmarks
from hkpd.camera_conventions import pixels_to_ndc
from hkpd.conditioning.evidence_term import PosedBodies

HAND_ROWS = (0, 1, 2, 3, 4, 5)
"""Rows of BlazePose's extremities (its landmarks 17-22) on the hands; 6-9 are on the feet."""


@dataclass(frozen=True)
class LandmarkConfig:
    """How much the landmarks pull.

    The hands' default is BlazePose's measured spread about the body model's landmarks relative
    to its spread about the COCO keypoints, on 200 synthetic renders
    (``docs/experiments/extremity_landmark_noise.py``: per-coordinate robust sigma 2.19 % of the
    crop side on the hands, 1.81 % on the feet, 1.18 % on the keypoints). The feet's is looser
    than their measured 1.55×: at 1.55× the fitted feet were more over-confident than with the
    keypoints alone (90 % coverage 0.43 against 0.56 on the synthetic test views); at 3.0× they
    keep most of their calibration (0.53) and their mode is closer (``docs/evidence.md``).

    Attributes:
        hand_sigma_scale: a hand landmark's sigma as a multiple of the keypoint sigma.
        foot_sigma_scale: a foot landmark's sigma as a multiple of the keypoint sigma.
        robust_scale: the Cauchy scale in sigmas (None: the keypoints').
    """

    hand_sigma_scale: float = 1.85
    foot_sigma_scale: float = 3.0
    robust_scale: float | None = None

    def __post_init__(self) -> None:
        for name in ("hand_sigma_scale", "foot_sigma_scale"):
            value = getattr(self, name)
            if not (value > 0 and value < float("inf")):
                raise ValueError(f"LandmarkConfig.{name} must be a finite number > 0, got {value}")
        if self.robust_scale is not None and not self.robust_scale > 0:
            raise ValueError(f"LandmarkConfig.robust_scale must be > 0, got {self.robust_scale}")


@dataclass(frozen=True)
class LandmarkEvidence:
    """Detected landmarks in the network's crop.

    Attributes:
        landmarks: ``(L, 2)`` crop pixels.
        observed: ``(L,)`` bool, the landmarks that are evidence.
        crop_size: the crop's side in pixels.
    """

    landmarks: torch.Tensor
    observed: torch.Tensor
    crop_size: int

    def __post_init__(self) -> None:
        count = self.landmarks.shape[0]
        if self.landmarks.shape != (count, 2) or self.observed.shape != (count,):
            raise ValueError(
                f"expected landmarks (L, 2) and observed (L,), got {tuple(self.landmarks.shape)} "
                f"and {tuple(self.observed.shape)}"
            )


class LandmarkTerm:
    """The hand and foot landmarks as an :class:`~hkpd.conditioning.EvidenceTerm`.

    Args:
        evidence: the detected landmarks, rows matching ``regressor``'s.
        regressor: the landmarks on the body model (:func:`hkpd.body.extremity_landmarks.
            extremity_landmarks`, its first 10 rows for BlazePose's extremities).
        keypoint_sigma: the keypoint sigma (fraction of the crop side), scaled per group.
        keypoint_robust_scale: the keypoints' Cauchy scale, used unless ``config`` sets one.
        config: the per-group sigma scales.
        hand_rows: which rows are on the hands (the rest are on the feet).
    """

    name = "landmarks"
    needs_vertices = False

    def __init__(
        self,
        evidence: LandmarkEvidence,
        regressor: ExtremityLandmarks,
        keypoint_sigma: float,
        keypoint_robust_scale: float | None,
        config: LandmarkConfig | None = None,
        hand_rows: tuple[int, ...] = HAND_ROWS,
    ) -> None:
        config = config or LandmarkConfig()
        count = evidence.landmarks.shape[0]
        if regressor.weights.shape[0] != count:
            raise ValueError(f"{count} detected landmarks for a regressor of "
                             f"{regressor.weights.shape[0]}")  # fmt: skip
        dtype = torch.float64
        self.regressor = regressor
        self.residual_shape = (count, 2)
        self.robust_scale: float | None = (
            config.robust_scale if config.robust_scale is not None else keypoint_robust_scale
        )
        self.targets = pixels_to_ndc(evidence.landmarks.to(dtype), evidence.crop_size)
        self.observed = evidence.observed.to(dtype)
        scale = torch.full((count,), config.foot_sigma_scale, dtype=dtype)
        scale[list(hand_rows)] = config.hand_sigma_scale
        self.sigma_ndc = 2.0 * keypoint_sigma * scale  # (L,): NDC spans 2 per crop side

    @property
    def surface_vertices(self) -> torch.Tensor:
        """``(P,)`` the vertices the landmark regressor reads."""
        return self.regressor.vertex_indices

    def residuals(self, posed: PosedBodies) -> torch.Tensor:
        """``(N, B, L, 2)`` reprojection residuals in sigmas (zero where no evidence)."""
        points = self.regressor.of_subset(posed.surface[self.name])  # (N, B, L, 3)
        ndc = posed.project(points)
        return (ndc - self.targets) / self.sigma_ndc[:, None] * self.observed[:, None]

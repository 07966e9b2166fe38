"""The fit's residuals: reprojection of the body's keypoints, and the priors as squares.

The fit minimises the negative log posterior ``-w log p_net(pose, shape) - log L(keypoints)``
plus weak priors that keep the global rotation and the camera near their start. Every term is
a sum of squares (the reprojection one robustified), which is what Levenberg-Marquardt wants:

- **Pose prior, exact.** For ``F = U S V^T`` and ``Q = U^T R V`` with unit quaternion
  ``(x, y, z, w)``, ``tr(S) - tr(F^T R) = 2 ((s2+s3) x² + (s1+s3) y² + (s1+s2) z²)`` (the
  sampler's Bingham form), so ``-w log p(R) + const`` is ``½ |r|²`` with
  ``r = 2 sqrt(w (s_j + s_k)) (x, y, z)``: no approximation, at any distance from the mode.
- **Shape prior.** ``r = sqrt(w) (β - μ) / σ``.
- **Keypoints.** ``r_k = (π(X_k) - y_k) / σ_kp`` in crop NDC, for evidence keypoints only;
  weighted by the Cauchy loss's IRLS weights in the solver.

Parameters are perturbations about the current estimate (85 per start): body joints
``R_j Exp(δ_j)`` (69, radians), global ``Exp(δ_g) R_g`` (3, radians, camera frame), camera
log-scale and translation (3), shape (10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import pixels_to_ndc
from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.keypoint_evidence import KeypointEvidence
from hkpd.distributions import BodyDistribution, proper_svd

NUM_BODY_JOINTS = 23
POSE = slice(0, 69)
GLOBAL = slice(69, 72)
CAMERA = slice(72, 75)
SHAPE = slice(75, 85)
NUM_PARAMETERS = 85
NUM_KEYPOINTS = 17


@dataclass(frozen=True)
class FitState:
    """The current estimate of B starts.

    Attributes:
        pose: ``(B, 23, 4)`` unit quaternions (XYZW) of the relative joint rotations.
        global_quat: ``(B, 4)`` unit quaternion of the global rotation.
        log_scale: ``(B,)`` log of the camera scale.
        translation: ``(B, 2)`` camera translation, metres.
        betas: ``(B, K)``.
    """

    pose: torch.Tensor
    global_quat: torch.Tensor
    log_scale: torch.Tensor
    translation: torch.Tensor
    betas: torch.Tensor

    @classmethod
    def from_estimate(cls, estimate: BodyDistribution, body_pose: torch.Tensor) -> FitState:
        """The start: ``body_pose (B, 23, 3, 3)`` and the estimate's global rotation, camera and
        mean shape."""
        return cls(
            pose=roma.rotmat_to_unitquat(body_pose),
            global_quat=roma.rotmat_to_unitquat(estimate.global_orient),
            log_scale=torch.log(estimate.camera[:, 0]),
            translation=estimate.camera[:, 1:],
            betas=estimate.shape_mean,
        )

    def retract(self, delta: torch.Tensor) -> FitState:
        """The state moved by ``delta (..., B, 85)`` (leading dims broadcast over copies)."""
        lead = delta.shape[:-2]
        pose_step = roma.rotvec_to_unitquat(delta[..., POSE].reshape(*lead, -1, NUM_BODY_JOINTS, 3))
        global_step = roma.rotvec_to_unitquat(delta[..., GLOBAL])
        return FitState(
            pose=roma.quat_product(self.pose.expand_as(pose_step), pose_step),
            global_quat=roma.quat_product(global_step, self.global_quat.expand_as(global_step)),
            log_scale=self.log_scale + delta[..., CAMERA][..., 0],
            translation=self.translation + delta[..., CAMERA][..., 1:],
            betas=self.betas + delta[..., SHAPE],
        )

    def copy(self, index: int) -> FitState:
        """Copy ``index`` of a state with leading dims ``(N, B)``, leading dim ``(B,)``."""
        return FitState(*(getattr(self, name)[index] for name in _FIELDS))

    def select(self, keep: torch.Tensor, other: FitState) -> FitState:
        """Per start: this state where ``keep (B,)`` is True, else ``other``."""

        def pick(mine: torch.Tensor, theirs: torch.Tensor) -> torch.Tensor:
            mask = keep.reshape(-1, *([1] * (mine.dim() - 1)))
            return torch.where(mask, mine, theirs)

        return FitState(*(pick(getattr(self, name), getattr(other, name)) for name in _FIELDS))

    def body_pose(self) -> torch.Tensor:
        """``(..., 23, 3, 3)`` relative joint rotation matrices."""
        return roma.unitquat_to_rotmat(self.pose)

    def global_orient(self) -> torch.Tensor:
        """``(..., 3, 3)`` global rotation matrix."""
        return roma.unitquat_to_rotmat(self.global_quat)

    def camera(self) -> torch.Tensor:
        """``(..., 3)`` weak-perspective camera ``[s, tx, ty]``."""
        return torch.cat((self.log_scale.exp().unsqueeze(-1), self.translation), dim=-1)


_FIELDS = ("pose", "global_quat", "log_scale", "translation", "betas")


@dataclass(frozen=True)
class Residuals:
    """Residuals of N copies of B states.

    Attributes:
        keypoints: ``(N, B, 17, 2)`` reprojection residuals in sigmas (zero where no evidence).
        priors: ``(N, B, P)`` pose, shape, global-rotation and camera prior residuals.
    """

    keypoints: torch.Tensor
    priors: torch.Tensor

    def squared_keypoint_errors(self) -> torch.Tensor:
        """``(N, B, 17)`` squared reprojection error per keypoint, in sigmas²."""
        return self.keypoints.square().sum(-1)

    def stacked(self, keypoint_weights: torch.Tensor) -> torch.Tensor:
        """``(N, B, 34 + P)``: keypoint residuals scaled by ``sqrt(weights (B, 17))``, then the
        priors."""
        scaled = self.keypoints * keypoint_weights.sqrt().unsqueeze(-1)
        return torch.cat((scaled.flatten(-2), self.priors), dim=-1)


class FitResiduals:
    """Residual function of one photo's fit, for B starts with their own priors.

    Args:
        body: the body model, float64 (finite differences need the precision).
        priors: the B network predictions; each start is regularised by its own.
        evidence: the observed keypoints (shared by all starts).
        config: prior weight, keypoint sigma and the weak priors' widths.
    """

    def __init__(
        self,
        body: BodyModel,
        priors: BodyDistribution,
        evidence: KeypointEvidence,
        config: EvidenceConfig,
    ) -> None:
        dtype = torch.float64
        if body.dtype != dtype:
            raise ValueError("the fit needs a float64 body model (body.double() makes one)")
        self.body = body
        self.config = config
        self.priors = priors.to(dtype)
        U, S, V = proper_svd(self.priors.F)
        s1, s2, s3 = S.unbind(-1)
        concentration = torch.stack((s2 + s3, s1 + s3, s1 + s2), dim=-1).clamp_min(0.0)
        self.pose_prior_scale = 2.0 * (config.prior_weight * concentration).sqrt()  # (B, 23, 3)
        self.prior_mode = U @ V.transpose(-1, -2)
        self.u_conjugate = roma.quat_conjugation(roma.rotmat_to_unitquat(U))
        self.v_quat = roma.rotmat_to_unitquat(V)
        self.shape_prior_scale = config.prior_weight**0.5 / self.priors.shape_std
        self.global_start_conjugate = roma.quat_conjugation(
            roma.rotmat_to_unitquat(self.priors.global_orient)
        )
        self.camera_start = torch.cat(
            (self.priors.camera[:, :1].log(), self.priors.camera[:, 1:]), dim=-1
        )
        size = evidence.crop_size
        self.targets = pixels_to_ndc(evidence.keypoints.to(dtype), size)  # (17, 2)
        self.observed = evidence.observed.to(dtype)  # (17,)
        self.sigma_ndc = 2.0 * config.keypoint_sigma

    def __call__(self, state: FitState) -> Residuals:
        """Residuals of ``state`` whose tensors have leading dims ``(N, B)``."""
        lead = state.betas.shape[:-1]
        flat = math.prod(lead)
        body_pose = state.body_pose().reshape(flat, NUM_BODY_JOINTS, 3, 3)
        keypoints, joints = self.body.posed_keypoints(
            state.betas.reshape(flat, -1), body_pose, state.global_orient().reshape(flat, 3, 3)
        )
        relative = (keypoints - joints[:, :1]).reshape(*lead, NUM_KEYPOINTS, 3)
        camera = state.camera()
        ndc = camera[..., :1, None] * (relative[..., :2] + camera[..., None, 1:])
        keypoint_residuals = (ndc - self.targets) / self.sigma_ndc * self.observed[:, None]

        in_frame = roma.quat_product(
            roma.quat_product(self.u_conjugate.expand_as(state.pose), state.pose),
            self.v_quat.expand_as(state.pose),
        )
        pose_prior = (in_frame[..., :3] * self.pose_prior_scale).flatten(-2)
        shape_prior = (state.betas - self.priors.shape_mean) * self.shape_prior_scale
        global_offset = roma.quat_product(
            self.global_start_conjugate.expand_as(state.global_quat), state.global_quat
        )
        global_prior = roma.unitquat_to_rotvec(global_offset) / self.config.global_rotation_sigma
        camera_now = torch.cat((state.log_scale.unsqueeze(-1), state.translation), dim=-1)
        camera_prior = (camera_now - self.camera_start) / self.config.camera_sigma
        priors = torch.cat((pose_prior, shape_prior, global_prior, camera_prior), dim=-1)
        return Residuals(keypoint_residuals, priors)

    def start(self) -> FitState:
        """Each start at its own prior's mode."""
        return FitState.from_estimate(self.priors, self.prior_mode)

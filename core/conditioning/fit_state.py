"""The fit's unknowns: the state of B starts and its 85 perturbation parameters.

Parameters are perturbations about the current estimate (85 per start): body joints
``R_j Exp(δ_j)`` (69, radians), global ``Exp(δ_g) R_g`` (3, radians, camera frame), camera
log-scale and translation (3), shape (10).
"""

from __future__ import annotations

from dataclasses import dataclass

import roma
import torch

from hkpd.distributions import BodyDistribution

NUM_BODY_JOINTS = 23
POSE = slice(0, 69)
GLOBAL = slice(69, 72)
CAMERA = slice(72, 75)
SHAPE = slice(75, 85)
NUM_PARAMETERS = 85


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

    def log_camera(self) -> torch.Tensor:
        """``(..., 3)`` the camera as the fit moves it: ``[log s, tx, ty]``."""
        return torch.cat((self.log_scale.unsqueeze(-1), self.translation), dim=-1)


_FIELDS = ("pose", "global_quat", "log_scale", "translation", "betas")

"""``NetworkOutput``: what the distribution-prediction network predicts for a batch."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch
from torch.distributions import Independent

from hkpd.distributions import KinematicMatrixFisher, body_shape_distribution
from hkpd.kinematic_tree import BODY_PARENTS


@dataclass
class NetworkOutput:
    """Predicted distributions and deterministic estimates for B proxy images.

    Attributes:
        F: ``(B, 23, 3, 3)`` matrix-Fisher parameters of the 23 body joints' rotations
            relative to their parents (order and tree: :data:`hkpd.kinematic_tree.BODY_PARENTS`).
        shape_mean: ``(B, K)`` mean shape coefficients.
        shape_std: ``(B, K)`` positive standard deviations of the shape coefficients.
        global_orient: ``(B, 3, 3)`` body-to-camera rotation (see
            :mod:`hkpd.camera_conventions`).
        camera: ``(B, 3)`` weak-perspective camera ``[s, tx, ty]``: ``s > 0`` in NDC units per
            metre, ``t`` in metres, acting on pelvis-relative camera-frame points.
    """

    F: torch.Tensor
    shape_mean: torch.Tensor
    shape_std: torch.Tensor
    global_orient: torch.Tensor
    camera: torch.Tensor

    @property
    def batch_size(self) -> int:
        return int(self.F.shape[0])

    def pose_distribution(self) -> KinematicMatrixFisher:
        """The distribution over the 23 relative joint rotations (batch shape ``(B,)``)."""
        return KinematicMatrixFisher(self.F, BODY_PARENTS)

    def shape_distribution(self) -> Independent:
        """The diagonal Gaussian over shape coefficients (batch ``(B,)``, event ``(K,)``)."""
        return body_shape_distribution(self.shape_mean, self.shape_std)

    def sample_betas(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """``(count, B, K)`` shape coefficients drawn from the shape Gaussian, reparameterised
        (``mean + std * noise``, so gradients reach ``shape_mean`` and ``shape_std``)."""
        noise = torch.randn(
            (count, *self.shape_mean.shape),
            generator=generator,
            dtype=self.shape_mean.dtype,
            device=self.shape_mean.device,
        )
        return self.shape_mean + self.shape_std * noise

    def detach(self) -> NetworkOutput:
        """A copy with every tensor detached from the autograd graph."""
        return NetworkOutput(**{f.name: getattr(self, f.name).detach() for f in fields(self)})

    def to(self, device: torch.device | str) -> NetworkOutput:
        """A copy with every tensor on ``device``."""
        return NetworkOutput(**{f.name: getattr(self, f.name).to(device) for f in fields(self)})

"""``FitPriors``: the prior block of the fit, every part an exact sum of squares.

The fit minimises ``-w log p_net(pose, shape) - log L(evidence)`` plus weak priors that keep
the global rotation and the camera near their start. The prior part is written as residuals
``r`` with ``½ |r|²`` equal to the negative log density (up to a constant), which is what
Levenberg-Marquardt wants:

- **Pose prior, exact.** For ``F = U S V^T`` and ``Q = U^T R V`` with unit quaternion
  ``(x, y, z, w)``, ``tr(S) - tr(F^T R) = 2 ((s2+s3) x² + (s1+s3) y² + (s1+s2) z²)`` (the
  sampler's Bingham form), so ``-w log p(R) + const`` is ``½ |r|²`` with
  ``r = 2 sqrt(w (s_j + s_k)) (x, y, z)``: no approximation, at any distance from the mode.
- **Shape prior.** ``r = sqrt(w) (β - μ) / σ``, or, when the fit is given a full-covariance
  shape prior (:class:`hkpd.conditioning.shape_prior.ShapeGaussian`: the network's reading
  re-based on one sex's population and conditioned on stated measurements, already tempered),
  ``r = R (β - μ)`` with ``Rᵀ R = Σ⁻¹``.
- **Global rotation and camera.** ``Log(R_g R_g0^T) / σ_g`` and
  ``([log s, tx, ty] - start) / σ_c`` (``EvidenceConfig.global_rotation_sigma``,
  ``camera_sigma``): the network predicts points, not distributions, for them.

It is a fixed block rather than an evidence term (:mod:`hkpd.conditioning.evidence_term`):
it reads the unknowns themselves, not the posed body, never robustified, and every fit has
exactly this one (the Laplace step's matrix-Fisher and Gaussian families rest on its form).
"""

from __future__ import annotations

from dataclasses import replace

import roma
import torch

from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.fit_state import FitState
from hkpd.conditioning.shape_prior import ShapeGaussian
from hkpd.distributions import BodyDistribution, proper_svd


class FitPriors:
    """The prior residuals of B starts, each regularised by its own network prediction.

    Args:
        priors: the B network predictions, float64.
        config: the prior weight and the weak priors' widths.
        shape_prior: B full-covariance shape priors replacing the network's tempered diagonal
            one (None: the network's).
    """

    def __init__(
        self,
        priors: BodyDistribution,
        config: EvidenceConfig,
        shape_prior: ShapeGaussian | None = None,
    ) -> None:
        self.config = config
        self.priors = priors
        self.shape_prior_mean = priors.shape_mean
        self.shape_prior_root: torch.Tensor | None = None
        if shape_prior is not None:
            self.shape_prior_mean = shape_prior.mean.to(priors.shape_mean)
            self.shape_prior_root = shape_prior.precision_root().to(priors.shape_mean)
        U, S, V = proper_svd(priors.F)
        s1, s2, s3 = S.unbind(-1)
        concentration = torch.stack((s2 + s3, s1 + s3, s1 + s2), dim=-1).clamp_min(0.0)
        self.pose_prior_scale = 2.0 * (config.prior_weight * concentration).sqrt()  # (B, 23, 3)
        self.prior_mode = U @ V.transpose(-1, -2)
        self.u_conjugate = roma.quat_conjugation(roma.rotmat_to_unitquat(U))
        self.v_quat = roma.rotmat_to_unitquat(V)
        self.shape_prior_scale = config.prior_weight**0.5 / priors.shape_std
        self.global_start_conjugate = roma.quat_conjugation(
            roma.rotmat_to_unitquat(priors.global_orient)
        )
        self.camera_start = torch.cat((priors.camera[:, :1].log(), priors.camera[:, 1:]), dim=-1)

    def __call__(self, state: FitState) -> torch.Tensor:
        """``(N, B, 69 + K + 3 + 3)`` pose, shape, global-rotation and camera prior residuals of
        ``state`` (leading dims ``(N, B)``)."""
        in_frame = roma.quat_product(
            roma.quat_product(self.u_conjugate.expand_as(state.pose), state.pose),
            self.v_quat.expand_as(state.pose),
        )
        pose_prior = (in_frame[..., :3] * self.pose_prior_scale).flatten(-2)
        offset = state.betas - self.shape_prior_mean
        if self.shape_prior_root is None:
            shape_prior = offset * self.shape_prior_scale
        else:
            shape_prior = torch.einsum("bkl,...bl->...bk", self.shape_prior_root, offset)
        global_offset = roma.quat_product(
            self.global_start_conjugate.expand_as(state.global_quat), state.global_quat
        )
        global_prior = roma.unitquat_to_rotvec(global_offset) / self.config.global_rotation_sigma
        camera_prior = (state.log_camera() - self.camera_start) / self.config.camera_sigma
        return torch.cat((pose_prior, shape_prior, global_prior, camera_prior), dim=-1)

    def start(self) -> FitState:
        """Each start at its own prior's mode (its shape at the shape prior's mean)."""
        state = FitState.from_estimate(self.priors, self.prior_mode)
        if self.shape_prior_root is None:
            return state
        return replace(state, betas=self.shape_prior_mean.clone())

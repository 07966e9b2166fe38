"""The matrix-Fisher distribution over rotation matrices, ``p(R | F) = exp(tr(F^T R)) / c(F)``."""

from __future__ import annotations

from typing import ClassVar

import roma
import torch
from torch.distributions import Distribution, constraints
from torch.distributions.utils import lazy_property

from hkpd.distributions.bingham_sampler import (
    SamplerError,
    draw_accepted_noise,
    kent_optimal_b,
    log_envelope_constant,
    proposal_transform,
)
from hkpd.distributions.normalizer import (
    log_normalizer_and_expectation,
    log_normalizer_value,
    matrix_fisher_log_normalizer,
)
from hkpd.distributions.proper_svd import proper_svd


class _RotationMatrices(constraints.Constraint):
    """Support of the distribution: 3x3 matrices with ``R^T R = I`` and ``det R = +1``."""

    event_dim = 2

    def check(self, value: torch.Tensor) -> torch.Tensor:
        tolerance = 1e-3 if value.dtype in (torch.float16, torch.bfloat16, torch.float32) else 1e-6
        eye = torch.eye(3, dtype=value.dtype, device=value.device)
        orthogonal = (
            ((value.transpose(-1, -2) @ value - eye).abs() <= tolerance).flatten(-2).all(-1)
        )
        proper = (torch.linalg.det(value) - 1.0).abs() <= tolerance
        return orthogonal & proper


rotation_matrices = _RotationMatrices()


def _frame_quaternion_map(U: torch.Tensor, V: torch.Tensor) -> torch.Tensor:
    """The 4x4 orthogonal map ``x -> q_U * x * conj(q_V)`` on XYZW quaternions, per distribution.

    Since quaternion products compose rotations, ``rotmat(q_U * x * conj(q_V)) = U rotmat(x) V^T``.
    The map is linear in ``x``; its matrix is found by applying roma's quaternion product to the
    four basis quaternions.

    Args:
        U, V: ``(N, 3, 3)`` rotation matrices.

    Returns:
        ``(N, 4, 4)`` matrices ``P`` with ``P @ x`` the transformed quaternion.
    """
    q_u, q_v = roma.rotmat_to_unitquat(torch.cat((U, V))).unsqueeze(-2).chunk(2)  # (N, 1, 4) each
    q_v_conj = roma.quat_conjugation(q_v)
    basis = torch.eye(4, dtype=U.dtype, device=U.device).expand(U.shape[0], 4, 4)
    images = roma.quat_product(roma.quat_product(q_u, basis), q_v_conj)  # row j = P e_j
    return images.transpose(-1, -2)


def _bingham_eigenvalues(S: torch.Tensor) -> torch.Tensor:
    """Diagonal ``(..., 4)`` of the Bingham matrix ``A`` for proper singular values ``(..., 3)``.

    For a rotation ``Q`` with quaternion ``(x, y, z, w)``,
    ``tr(diag(S) Q) = s1 + s2 + s3 - 2 ((s2+s3) x^2 + (s1+s3) y^2 + (s1+s2) z^2)``, i.e.
    ``sum(S) - q^T A q`` with, in roma's XYZW order, ``A = diag(2(s2+s3), 2(s1+s3), 2(s1+s2), 0)``
    (the paper's Algorithm 1 lists the same entries in WXYZ order).
    """
    s1, s2, s3 = S.unbind(-1)
    return torch.stack(
        (2.0 * (s2 + s3), 2.0 * (s1 + s3), 2.0 * (s1 + s2), torch.zeros_like(s1)), dim=-1
    ).clamp_min(0.0)


class MatrixFisher(Distribution):
    """Matrix-Fisher distribution ``M(R; F)`` on SO(3).

    Args:
        F: ``(..., 3, 3)`` parameter matrix. Batch shape ``F.shape[:-2]``, event shape ``(3, 3)``.
        validate_args: as in :class:`torch.distributions.Distribution`.

    With the proper SVD ``F = U diag(s1, s2, s3) V^T`` (``U, V`` in SO(3), ``s1 >= s2 >= |s3|``)
    the mode is ``U V^T``, the columns of ``U`` are the principal axes and the concentration for
    rotations about axis i is ``s_j + s_k``. The normaliser uses the Haar probability measure,
    so ``log c(0) = 0`` and ``F = 0`` is the uniform distribution.

    A float16 or bfloat16 ``F`` is promoted to float32 (samples and densities are float32).

    After :meth:`rsample`/:meth:`sample`, ``last_acceptance_rate`` holds the fraction of
    proposals the rejection sampler accepted for each distribution (batch shape).
    """

    arg_constraints: ClassVar[dict[str, constraints.Constraint]] = {
        "F": constraints.independent(constraints.real, 2)
    }
    support = rotation_matrices
    has_rsample = True

    def __init__(self, F: torch.Tensor, validate_args: bool | None = None) -> None:
        if F.dim() < 2 or F.shape[-2:] != (3, 3):
            raise ValueError(f"F must have shape (..., 3, 3), got {tuple(F.shape)}")
        if not F.is_floating_point():
            raise TypeError(f"F must be a floating-point tensor, got dtype {F.dtype}")
        if F.dtype in (torch.float16, torch.bfloat16):
            F = F.float()  # the SVD and the sampler need at least float32
        self.F = F
        self.last_acceptance_rate: torch.Tensor | None = None
        super().__init__(batch_shape=F.shape[:-2], event_shape=(3, 3), validate_args=validate_args)

    # ----------------------------------------------------------------------------- structure
    @lazy_property
    def _svd(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return proper_svd(self.F)

    @lazy_property
    def _svd64(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The proper SVD of ``F`` in float64, without gradient, for the density evaluations.

        At concentrations near 1e8 (the shipped model's hands) a float32 SVD's singular values
        are off by ~10 and ``tr(F^T R)`` loses whole nats to cancellation, so log-densities,
        entropies and acceptance rates are computed from this one and cast back.
        """
        if self.F.dtype == torch.float64 and not self.F.requires_grad:
            return self._svd
        return proper_svd(self.F.detach().to(torch.float64))

    def _log_j(self) -> torch.Tensor:
        """``(...)`` float64 ``log J = log c - tr S`` (no cancellation at large S)."""
        S64 = self._svd64[1]
        return log_normalizer_value(S64) - S64.sum(-1)

    @property
    def U(self) -> torch.Tensor:
        """``(..., 3, 3)`` left proper-SVD factor; its columns are the principal axes."""
        return self._svd[0]

    @property
    def S(self) -> torch.Tensor:
        """``(..., 3)`` proper singular values ``s1 >= s2 >= |s3|``."""
        return self._svd[1]

    @property
    def V(self) -> torch.Tensor:
        """``(..., 3, 3)`` right proper-SVD factor."""
        return self._svd[2]

    @property
    def mode(self) -> torch.Tensor:
        """``(..., 3, 3)`` most likely rotation, ``U V^T``."""
        return self.U @ self.V.transpose(-1, -2)

    @property
    def concentration(self) -> torch.Tensor:
        """``(..., 3)`` concentration ``s_j + s_k`` for rotations about each principal axis i."""
        s1, s2, s3 = self.S.unbind(-1)
        return torch.stack((s2 + s3, s1 + s3, s1 + s2), dim=-1)

    # ------------------------------------------------------------------------------ density
    @lazy_property
    def log_normalizer(self) -> torch.Tensor:
        """``(...)`` log c(F), differentiable with respect to ``F``."""
        return matrix_fisher_log_normalizer(self.S)

    @property
    def mean(self) -> torch.Tensor:
        """``(..., 3, 3)`` E[R] = d log c / dF = ``U diag(E[Q_ii]) V^T`` (not a rotation).

        Computed analytically by quadrature, without gradients.
        """
        with torch.no_grad():
            expected = log_normalizer_and_expectation(self.S)[1]
            return self.U @ torch.diag_embed(expected) @ self.V.transpose(-1, -2)

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        """Log density of rotations ``value (..., 3, 3)`` w.r.t. the Haar probability measure.

        The value is computed without cancellation, in float64: with ``Q = U^T R V`` as a unit
        quaternion ``(x, y, z, w)``, ``log p = -log J(S) - 2((s2+s3)x² + (s1+s3)y² + (s1+s2)z²)``
        (``log J = log c - tr S``), so a float32 ``F`` at concentration 1e8 gives the same
        log-density as float64 to ~1e-6 nats. Gradients are those of ``tr(F^T R) - log c(F)``
        (``R - E[R]`` for ``F``), exactly as before.
        """
        if self._validate_args:
            self._validate_sample(value)
        exact = self.log_prob_exact(value)
        if not (torch.is_grad_enabled() and (self.F.requires_grad or value.requires_grad)):
            return exact.to(torch.promote_types(self.F.dtype, value.dtype))
        plain = (self.F * value).sum((-1, -2)) - self.log_normalizer
        return plain + (exact.to(plain.dtype) - plain).detach()

    def log_prob_exact(self, value: torch.Tensor) -> torch.Tensor:
        """``log p(value)`` in float64, without gradient, from the quaternion form (see
        :meth:`log_prob`)."""
        U, S, V = self._svd64
        Q = U.transpose(-1, -2) @ value.detach().to(torch.float64) @ V
        x, y, z, _ = roma.rotmat_to_unitquat(Q).unbind(-1)
        s1, s2, s3 = S.unbind(-1)
        quadratic = (s2 + s3) * x * x + (s1 + s3) * y * y + (s1 + s2) * z * z
        return -self._log_j() - 2.0 * quadratic

    def entropy(self) -> torch.Tensor:
        """``(...)`` differential entropy w.r.t. Haar probability (<= 0, 0 iff uniform).

        Computed in float64 as ``log J + Σ s_i (1 - E[Q_ii])`` (no cancellation at large S);
        gradients, where ``F`` needs them, are those of ``log c - Σ s_i E[Q_ii]``.
        """
        S64 = self._svd64[1]
        log_c64, expected64 = log_normalizer_and_expectation(S64)
        exact = (log_c64 - S64.sum(-1)) + (S64 * (1.0 - expected64)).sum(-1)
        if not (torch.is_grad_enabled() and self.F.requires_grad):
            return exact.to(self.F.dtype)
        expected = log_normalizer_and_expectation(self.S)[1]
        plain = self.log_normalizer - (self.S * expected).sum(-1)
        return plain + (exact.to(plain.dtype) - plain).detach()

    # ----------------------------------------------------------------------------- sampling
    @lazy_property
    def _proposal(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Flattened Bingham eigenvalues ``(N, 4)`` and Kent's ``b (N,)``."""
        lambdas = _bingham_eigenvalues(self.S.reshape(-1, 3))
        return lambdas, kent_optimal_b(lambdas)

    @lazy_property
    def _frame_map(self) -> torch.Tensor:
        """``(N, 4, 4)`` quaternion map into the frames of ``U`` and ``V`` (see sampler)."""
        return _frame_quaternion_map(self.U.reshape(-1, 3, 3), self.V.reshape(-1, 3, 3))

    @property
    def expected_acceptance_rate(self) -> torch.Tensor:
        """``(...)`` exact acceptance probability of the Kent rejection sampler for these F.

        Equals ``|Omega|^(1/2) * 1F1(-A) / M`` with ``1F1(-A) = c(F) exp(-sum s)``.
        """
        with torch.no_grad():
            lambdas = _bingham_eigenvalues(self._svd64[1])
            b = kent_optimal_b(lambdas)
            omega = 1.0 + 2.0 * lambdas / b.unsqueeze(-1)
            log_rate = 0.5 * torch.log(omega).sum(-1) + self._log_j() - log_envelope_constant(b)
            return torch.exp(log_rate).to(self.F.dtype)

    def rsample(
        self,
        sample_shape: torch.Size | tuple[int, ...] = (),
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Reparameterised samples via the paper's Algorithm 1.

        Args:
            sample_shape: leading sample dimensions.
            generator: optional random generator.

        Returns:
            ``sample_shape + batch_shape + (3, 3)`` rotation matrices; gradients flow to ``F``
            through the proposal (for fixed noise) and through ``U`` and ``V``.
        """
        sample_shape = torch.Size(sample_shape)
        count = sample_shape.numel()
        if not bool(torch.isfinite(self.F).all()):
            raise SamplerError(
                "cannot sample a matrix-Fisher whose F has inf or NaN entries (at flat index "
                f"{torch.isfinite(self.F).logical_not().flatten(-2).any(-1).flatten().nonzero().flatten().tolist()[:8]})"
            )
        lambdas, b = self._proposal
        drawn = draw_accepted_noise(lambdas, b, count, generator=generator)
        self.last_acceptance_rate = drawn.acceptance_rate.reshape(self.batch_shape)
        quaternions = proposal_transform(lambdas, b, drawn.noise, self._frame_map)
        R = roma.unitquat_to_rotmat(quaternions.transpose(0, 1))  # (count, N, 3, 3)
        return R.reshape(sample_shape + self.batch_shape + (3, 3))

    def sample(
        self,
        sample_shape: torch.Size | tuple[int, ...] = (),
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Like :meth:`rsample`, without gradients."""
        with torch.no_grad():
            return self.rsample(sample_shape, generator=generator)

    def expand(self, batch_shape, _instance=None) -> MatrixFisher:
        batch_shape = torch.Size(batch_shape)
        return MatrixFisher(self.F.expand(*batch_shape, 3, 3), validate_args=False)

    def with_singular_values(self, S: torch.Tensor) -> MatrixFisher:
        """A distribution with the same principal axes and mode but proper singular values ``S``.

        The new distribution reuses this one's ``U``, ``V`` and sampler frame map instead of
        recomputing an SVD, so concentration edits (the explorer's sliders) stay cheap.

        Args:
            S: ``(..., 3)`` new proper singular values in proper order (``s1 >= s2 >= |s3|``),
                broadcastable to the batch shape; e.g. the current ones times a factor >= 0.
        """
        S = S.expand(*self.batch_shape, 3)
        if ((S[..., 0] < S[..., 1]) | (S[..., 1] < S[..., 2].abs())).any():
            raise ValueError("singular values must satisfy s1 >= s2 >= |s3|")
        F = self.U @ torch.diag_embed(S) @ self.V.transpose(-1, -2)
        edited = MatrixFisher(F, validate_args=self._validate_args)
        # lazy_property caches in the instance dict, so seeding it skips the recomputation.
        edited._svd = (self.U, S, self.V)
        if "_frame_map" in self.__dict__:
            edited._frame_map = self._frame_map
        return edited

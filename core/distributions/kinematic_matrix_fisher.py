"""A matrix-Fisher distribution over every relative joint rotation of a kinematic tree.

Given the per-joint parameters ``F_i`` (which a hierarchical network computes from the
ancestors' distributions), the relative rotations are conditionally independent, so sampling
and densities factorise over joints. This class adds what the tree brings: composing relative
rotations into global ones, and per-joint concentration edits.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import torch
from torch.distributions import Distribution, constraints
from torch.distributions.utils import lazy_property

from hkpd.distributions.matrix_fisher import MatrixFisher, rotation_matrices
from hkpd.kinematic_tree import compose_global_rotations, validate_parents


class KinematicMatrixFisher(Distribution):
    """Product of per-joint matrix-Fisher distributions over a kinematic tree's relative rotations.

    Args:
        F: ``(..., J, 3, 3)`` per-joint parameters; batch shape ``F.shape[:-3]``, event shape
            ``(J, 3, 3)``.
        parents: length-J parents array (-1 = child of the root), parents before children.
        validate_args: as in :class:`torch.distributions.Distribution`.
    """

    arg_constraints: ClassVar[dict[str, constraints.Constraint]] = {
        "F": constraints.independent(constraints.real, 3)
    }
    support = constraints.independent(rotation_matrices, 1)
    has_rsample = True

    def __init__(
        self, F: torch.Tensor, parents: Sequence[int], validate_args: bool | None = None
    ) -> None:
        self.parents = validate_parents(parents)
        joints = len(self.parents)
        if F.dim() < 3 or F.shape[-3:] != (joints, 3, 3):
            raise ValueError(
                f"F must have shape (..., {joints}, 3, 3) for a tree of {joints} joints, "
                f"got {tuple(F.shape)}"
            )
        self.F = F
        self.joints = MatrixFisher(F, validate_args=False)
        super().__init__(
            batch_shape=F.shape[:-3], event_shape=(joints, 3, 3), validate_args=validate_args
        )

    @property
    def num_joints(self) -> int:
        """Number of joints J."""
        return len(self.parents)

    @property
    def mode(self) -> torch.Tensor:
        """``(..., J, 3, 3)`` per-joint modal relative rotations."""
        return self.joints.mode

    @property
    def mean(self) -> torch.Tensor:
        """``(..., J, 3, 3)`` per-joint E[R] (not rotations)."""
        return self.joints.mean

    @property
    def concentration(self) -> torch.Tensor:
        """``(..., J, 3)`` concentration about each joint's three principal axes."""
        return self.joints.concentration

    @property
    def last_acceptance_rate(self) -> torch.Tensor | None:
        """``(..., J)`` rejection-sampler acceptance rate of the last sampling call."""
        return self.joints.last_acceptance_rate

    @lazy_property
    def log_normalizer(self) -> torch.Tensor:
        """``(..., J)`` per-joint log normalising constants."""
        return self.joints.log_normalizer

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        """``(...)`` joint log density of relative rotations ``value (..., J, 3, 3)``."""
        if self._validate_args:
            self._validate_sample(value)
        return self.joints.log_prob(value).sum(-1)

    def entropy(self) -> torch.Tensor:
        """``(...)`` sum of the per-joint entropies."""
        return self.joints.entropy().sum(-1)

    def rsample(
        self,
        sample_shape: int | torch.Size | tuple[int, ...] = (),
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Reparameterised samples of all relative rotations.

        Args:
            sample_shape: an int K or a shape.
            generator: optional random generator.

        Returns:
            ``sample_shape + batch_shape + (J, 3, 3)``; for ``K`` and batch ``(B,)`` that is
            ``(K, B, J, 3, 3)``.
        """
        if isinstance(sample_shape, int):
            sample_shape = (sample_shape,)
        return self.joints.rsample(torch.Size(sample_shape), generator=generator)

    def sample(
        self,
        sample_shape: int | torch.Size | tuple[int, ...] = (),
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Like :meth:`rsample`, without gradients."""
        with torch.no_grad():
            return self.rsample(sample_shape, generator=generator)

    def global_rotations(
        self, relative: torch.Tensor, root: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Compose relative rotations ``(..., J, 3, 3)`` into global ones along this tree.

        See :func:`compose_global_rotations`.
        """
        return compose_global_rotations(relative, self.parents, root)

    def scale_concentration(
        self, joints: int | Sequence[int] | torch.Tensor, factor: float | torch.Tensor
    ) -> KinematicMatrixFisher:
        """A new distribution with the selected joints' proper singular values times ``factor``.

        Principal axes and modes are unchanged; the concentrations ``s_j + s_k`` of the selected
        joints scale by ``factor``. This is what the explorer's concentration sliders do.

        Args:
            joints: a joint index, a sequence of indices, or a boolean mask of shape ``(J,)``.
            factor: a positive scalar, or a tensor broadcastable to ``batch_shape`` (or to
                ``batch_shape + (J,)`` when ``joints`` selects all joints by mask).

        Returns:
            A :class:`KinematicMatrixFisher` with the same parents.
        """
        mask = torch.zeros(self.num_joints, dtype=torch.bool, device=self.F.device)
        if isinstance(joints, torch.Tensor) and joints.dtype == torch.bool:
            if joints.shape != (self.num_joints,):
                raise ValueError(f"joint mask must have shape ({self.num_joints},)")
            mask = joints.to(self.F.device)
        else:
            index = torch.as_tensor(joints, dtype=torch.long).reshape(-1)
            if ((index < -self.num_joints) | (index >= self.num_joints)).any():
                raise IndexError(f"joint index out of range for {self.num_joints} joints: {joints}")
            mask[index.to(self.F.device)] = True
        factor = torch.as_tensor(factor, dtype=self.F.dtype, device=self.F.device)
        if not bool(torch.isfinite(factor).all()) or bool((factor < 0).any()):
            raise ValueError(f"concentration factors must be finite and non-negative, got {factor}")
        if factor.dim() == len(self.batch_shape):
            factor = factor.unsqueeze(-1)
        scale = torch.where(mask, factor, torch.ones_like(factor))
        scaled = self.joints.with_singular_values(self.joints.S * scale.unsqueeze(-1))
        edited = KinematicMatrixFisher(scaled.F, self.parents, validate_args=self._validate_args)
        edited.joints = scaled  # keeps the SVD and sampler frames that scaled reuses
        return edited

    def expand(self, batch_shape, _instance=None) -> KinematicMatrixFisher:
        batch_shape = torch.Size(batch_shape)
        F = self.F.expand(batch_shape + self.F.shape[-3:])
        return KinematicMatrixFisher(F, self.parents, validate_args=False)

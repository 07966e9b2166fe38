"""``BodyDistribution``: one record for a distribution over bodies, wherever it comes from.

The network predicts it (:class:`hkpd.network.DistributionNetwork`), the keypoint fit starts
from it and returns one (:mod:`hkpd.conditioning`), and a photo's posterior wraps one with its
crop and provenance (:class:`hkpd.prediction.BodyPosterior`). Its fields are declared here once.

The record holds any leading batch shape ``(*B)``: ``(B,)`` for a network batch or the fit's
starts, ``()`` for one person's posterior.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

import torch
from torch.distributions import Independent

from hkpd.distributions.body_shape import body_shape_distribution
from hkpd.distributions.kinematic_matrix_fisher import KinematicMatrixFisher
from hkpd.kinematic_tree import BODY_PARENTS


@dataclass(frozen=True)
class BodyDistribution:
    """A distribution over bodies: pose, shape, and the point estimates that place them.

    Attributes:
        F: ``(*B, 23, 3, 3)`` matrix-Fisher parameters of the 23 body joints' rotations
            relative to their parents (order and tree: :data:`hkpd.kinematic_tree.BODY_PARENTS`);
            the distribution is hierarchical (:class:`KinematicMatrixFisher`).
        shape_mean: ``(*B, K)`` mean shape coefficients (K = 10, unitless).
        shape_std: ``(*B, K)`` positive standard deviations of the shape coefficients.
        global_orient: ``(*B, 3, 3)`` body-to-camera rotation (see
            :mod:`hkpd.camera_conventions`), a point estimate.
        camera: ``(*B, 3)`` weak-perspective camera ``[s, tx, ty]`` of the network's crop:
            ``s > 0`` in NDC units per metre, ``t`` in metres, acting on pelvis-relative
            camera-frame points; a point estimate.
    """

    F: torch.Tensor
    shape_mean: torch.Tensor
    shape_std: torch.Tensor
    global_orient: torch.Tensor
    camera: torch.Tensor

    def __repr__(self) -> str:
        """One line: the batch shape, the shapes of ``F`` and ``shape_mean``, the dtype and
        device (never the numbers: the default repr of an unbatched record was 3.9 kB)."""
        shapes = ", ".join(
            f"{name}={tuple(getattr(tensor, 'shape', ()))}"
            for name, tensor in zip(("F", "shape_mean"), (self.F, self.shape_mean), strict=True)
        )
        batch = tuple(getattr(self.F, "shape", ())[:-3])
        dtype = str(getattr(self.F, "dtype", "?")).removeprefix("torch.")
        return (
            f"BodyDistribution(batch_shape={batch}, {shapes}, {dtype}, "
            f"{getattr(self.F, 'device', '?')})"
        )

    @property
    def batch_size(self) -> int:
        """Size of the first batch dimension (the record must be batched)."""
        return int(self.F.shape[0])

    def tensors(self) -> tuple[torch.Tensor, ...]:
        """The five tensors, in field order."""
        return tuple(getattr(self, field.name) for field in fields(self))

    def map(self, function: Callable[[torch.Tensor], torch.Tensor]) -> BodyDistribution:
        """A record with ``function`` applied to every tensor (e.g. a dtype, device or index)."""
        return BodyDistribution(*(function(tensor) for tensor in self.tensors()))

    def to(self, *args: object, **kwargs: object) -> BodyDistribution:
        """A copy with every tensor moved or cast as ``torch.Tensor.to(*args, **kwargs)``."""
        return self.map(lambda tensor: tensor.to(*args, **kwargs))

    def detach(self) -> BodyDistribution:
        """A copy with every tensor detached from the autograd graph."""
        return self.map(torch.Tensor.detach)

    def rows(self, index: int | slice | torch.Tensor) -> BodyDistribution:
        """The batch entries ``index`` (an int drops the batch dimension)."""
        return self.map(lambda tensor: tensor[index])

    def where(self, take: torch.Tensor, other: BodyDistribution) -> BodyDistribution:
        """Per batch entry, this record where ``take`` (``(B,)`` bool) is True, else ``other``."""
        return BodyDistribution(
            *(
                torch.where(take.view(-1, *[1] * (mine.ndim - 1)), mine, theirs)
                for mine, theirs in zip(self.tensors(), other.tensors(), strict=True)
            )
        )

    def is_finite(self) -> bool:
        """Every number finite and every shape std positive."""
        return all(bool(torch.isfinite(tensor).all()) for tensor in self.tensors()) and bool(
            (self.shape_std > 0).all()
        )

    def pose_distribution(self) -> KinematicMatrixFisher:
        """The distribution over the 23 relative joint rotations (batch shape ``(B,)``)."""
        return KinematicMatrixFisher(self.F, BODY_PARENTS)

    def shape_distribution(self) -> Independent:
        """The diagonal Gaussian over shape coefficients (batch ``(B,)``, event ``(K,)``)."""
        return body_shape_distribution(self.shape_mean, self.shape_std)

    def sample_betas(self, count: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """``(count, *B, K)`` shape coefficients drawn from the shape Gaussian, reparameterised
        (``mean + std * noise``, so gradients reach ``shape_mean`` and ``shape_std``)."""
        noise = torch.randn(
            (count, *self.shape_mean.shape),
            generator=generator,
            dtype=self.shape_mean.dtype,
            device=self.shape_mean.device,
        )
        return self.shape_mean + self.shape_std * noise

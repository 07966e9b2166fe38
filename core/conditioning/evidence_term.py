"""``EvidenceTerm``: one kind of evidence the fit weighs, and ``PosedBodies``, what it reads.

The fit minimises ``½ Σ_terms Σ_groups ρ_t(|r_tg|²) + ½ |r_prior|²`` over the 85 unknowns of
each start (:mod:`hkpd.conditioning.fit_state`). An evidence term turns the posed bodies of the
states the solver evaluates into residuals in units of their noise (sigmas), grouped: a group
(e.g. one keypoint's two coordinates) is what the robust loss ``ρ_t`` acts on, through the
group's squared norm. The solver (:mod:`hkpd.conditioning.levenberg_marquardt`) and the Laplace
step (:mod:`hkpd.conditioning.keypoint_fit`) know terms only through this interface, so a new
kind of evidence is a new class here, not a change there (``docs/architecture.md``, "Add an
evidence term").

The prior (the network's distribution, tempered, and the weak global-rotation and camera
priors) is not a term: it reads the unknowns rather than the posed body, every fit has exactly
one, and the Laplace step's families rest on its form (:mod:`hkpd.conditioning.fit_priors`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import torch


@dataclass(frozen=True)
class PosedBodies:
    """What the body model gives for the ``(N, B)`` states one solver call evaluates (N copies,
    e.g. the finite-difference perturbations, of B starts), float64.

    Attributes:
        keypoints: ``(N, B, 17, 3)`` COCO keypoints, metres, body frame turned by the global
            rotation (the camera's axes; the root joint at its rest location).
        joints: ``(N, B, 24, 3)`` joints, same frame.
        vertices: ``(N, B, V, 3)`` mesh vertices, same frame; None unless a term of the fit
            asks for them (:attr:`EvidenceTerm.needs_vertices`: posing them costs ~50× more).
        camera: ``(N, B, 3)`` weak-perspective camera ``[s, tx, ty]``.
        betas: ``(N, B, K)`` shape coefficients.
        surface: per name of a term that asks for a few mesh vertices
            (:attr:`EvidenceTerm.surface_vertices`), those vertices posed, ``(N, B, P, 3)``,
            same frame: posing a few hundred costs a fraction of the whole mesh.
    """

    keypoints: torch.Tensor
    joints: torch.Tensor
    vertices: torch.Tensor | None
    camera: torch.Tensor
    betas: torch.Tensor
    surface: Mapping[str, torch.Tensor] = field(default_factory=dict)

    def project(self, points: torch.Tensor) -> torch.Tensor:
        """``(N, B, P, 3)`` points (metres, this frame) -> ``(N, B, P, 2)`` crop NDC, relative to
        the root joint as the network's camera is: ``s (x - root + t)``."""
        relative = points - self.joints[..., :1, :]
        return self.camera[..., :1, None] * (relative[..., :2] + self.camera[..., None, 1:])


class EvidenceTerm(Protocol):
    """One kind of evidence in the fit (the keypoints: :class:`~hkpd.conditioning.KeypointTerm`).

    A term holds its observation (already on the fit's device, float64) and is evaluated many
    times per fit: keep :meth:`residuals` to batched tensor arithmetic, differentiable in the
    posed body (the solver takes forward differences, step 1e-6).
    """

    @property
    def name(self) -> str:
        """Unique within a fit; names the term's robust weights in the solver's result."""
        ...

    @property
    def residual_shape(self) -> tuple[int, int]:
        """``(groups, components)``: the shape of one state's residuals."""
        ...

    @property
    def robust_scale(self) -> float | None:
        """The Cauchy loss's scale in sigmas (a group's loss turns from quadratic to
        logarithmic there), or None for plain least squares."""
        ...

    @property
    def needs_vertices(self) -> bool:
        """Whether :meth:`residuals` reads ``posed.vertices`` (the whole mesh)."""
        ...

    @property
    def surface_vertices(self) -> torch.Tensor | None:
        """``(P,)`` long indices of the mesh vertices :meth:`residuals` reads as
        ``posed.surface[name]`` (posed by a model of those vertices alone), or None."""
        ...

    def residuals(self, posed: PosedBodies) -> torch.Tensor:
        """``(N, B, groups, components)`` residuals in sigmas (zero where there is no
        evidence: a zero residual adds nothing to the cost, the gradient or the Hessian)."""
        ...

"""``FitObjective``: one photo's fit as residuals, the evidence terms' and the prior's.

The cost is ``½ Σ_t Σ_g ρ_t(|r_tg|²) + ½ |r_prior|²``: each evidence term
(:class:`~hkpd.conditioning.EvidenceTerm`, robustified by its own Cauchy scale or not) reads
the posed bodies, the prior block (:class:`~hkpd.conditioning.fit_priors.FitPriors`) the
unknowns. The body is posed once per evaluation for all terms, with its vertices only when a
term asks for them, and the few surface vertices a term names (``surface_vertices``) by a model
of those vertices alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from hkpd.body import BodyModel
from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.evidence_term import EvidenceTerm, PosedBodies
from hkpd.conditioning.fit_priors import FitPriors
from hkpd.conditioning.fit_state import NUM_BODY_JOINTS, FitState
from hkpd.conditioning.shape_prior import ShapeGaussian
from hkpd.conditioning.surface_points import vertex_subset_model
from hkpd.distributions import BodyDistribution


@dataclass(frozen=True)
class Residuals:
    """Residuals of N copies of B states.

    Attributes:
        evidence: per evidence term of the objective, in its order, ``(N, B, groups,
            components)`` in sigmas.
        priors: ``(N, B, P)`` pose, shape, global-rotation and camera prior residuals.
    """

    evidence: tuple[torch.Tensor, ...]
    priors: torch.Tensor

    def first(self) -> Residuals:
        """The first copy only (leading dims ``(1, B)``)."""
        return Residuals(tuple(values[:1] for values in self.evidence), self.priors[:1])

    def stacked(self, weights: Sequence[torch.Tensor]) -> torch.Tensor:
        """``(N, B, M)``: each term's residuals scaled by ``sqrt(weights (B, groups))`` of its
        groups, flattened, in term order, then the priors."""
        scaled = [
            (values * weight.sqrt().unsqueeze(-1)).flatten(-2)
            for values, weight in zip(self.evidence, weights, strict=True)
        ]
        return torch.cat((*scaled, self.priors), dim=-1)


class FitObjective:
    """Residual function of one photo's fit, for B starts with their own priors.

    Args:
        body: the body model, float64 (finite differences need the precision).
        priors: the B network predictions; each start is regularised by its own.
        terms: the evidence terms (at least one; unique names).
        config: the prior weight and the weak priors' widths.
        shape_prior: B full-covariance shape priors instead of the network's (see
            :class:`~hkpd.conditioning.fit_priors.FitPriors`).
    """

    def __init__(
        self,
        body: BodyModel,
        priors: BodyDistribution,
        terms: Sequence[EvidenceTerm],
        config: EvidenceConfig,
        shape_prior: ShapeGaussian | None = None,
    ) -> None:
        if body.dtype != torch.float64:
            raise ValueError("the fit needs a float64 body model (body.double() makes one)")
        names = [term.name for term in terms]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"the fit needs one or more evidence terms with unique names: {names}")
        self.body = body
        self.terms = tuple(terms)
        self.prior = FitPriors(priors.to(torch.float64), config, shape_prior)
        self.needs_vertices = any(term.needs_vertices for term in self.terms)
        self.surface_models = {
            term.name: vertex_subset_model(body, term.surface_vertices)
            for term in self.terms
            if term.surface_vertices is not None
        }

    def pose(self, state: FitState) -> PosedBodies:
        """The bodies of ``state`` (leading dims ``(N, B)``), vertices only when needed."""
        lead = state.betas.shape[:-1]
        flat = math.prod(lead)
        betas = state.betas.reshape(flat, -1)
        body_pose = state.body_pose().reshape(flat, NUM_BODY_JOINTS, 3, 3)
        orient = state.global_orient().reshape(flat, 3, 3)
        vertices = None
        if self.needs_vertices:
            output = self.body(betas, body_pose, orient)
            if output.keypoints is None:
                raise ValueError("this body model has no COCO keypoint regressor")
            keypoints, joints = output.keypoints, output.joints
            vertices = output.vertices.reshape(*lead, -1, 3)
        else:
            keypoints, joints = self.body.posed_keypoints(betas, body_pose, orient)
        surface = {
            name: model(betas, body_pose, orient).vertices.reshape(*lead, -1, 3)
            for name, model in self.surface_models.items()
        }
        return PosedBodies(
            keypoints=keypoints.reshape(*lead, -1, 3),
            joints=joints.reshape(*lead, -1, 3),
            vertices=vertices,
            camera=state.camera(),
            betas=state.betas,
            surface=surface,
        )

    def __call__(self, state: FitState) -> Residuals:
        """Residuals of ``state`` whose tensors have leading dims ``(N, B)``."""
        posed = self.pose(state)
        lead = tuple(state.betas.shape[:-1])
        evidence = []
        for term in self.terms:
            values = term.residuals(posed)
            if tuple(values.shape) != (*lead, *term.residual_shape):
                raise ValueError(
                    f"evidence term {term.name!r} returned residuals of shape "
                    f"{tuple(values.shape)}, expected {(*lead, *term.residual_shape)}"
                )
            evidence.append(values)
        return Residuals(tuple(evidence), self.prior(state))

    def robust_scales(self) -> tuple[float | None, ...]:
        """Each term's Cauchy scale (None: plain least squares), in term order."""
        return tuple(term.robust_scale for term in self.terms)

    def start(self) -> FitState:
        """Each start at its own prior's mode."""
        return self.prior.start()

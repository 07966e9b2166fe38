"""Condition the network's body distribution on 2D keypoints: fit, then Laplace back to the family.

:func:`condition_on_keypoints` runs the batched Levenberg-Marquardt fit
(:mod:`hkpd.conditioning.levenberg_marquardt`) of pose, global rotation, camera and shape to
the evidence, from every start (e.g. the network run on the crop and on the crop rotated
upright) and, with ``EvidenceConfig.facings`` 2 (the default), from each start turned 180°
about the body's vertical axis where that copy explains the keypoints better before the fit
(:mod:`hkpd.conditioning.facing`), all in one batch; keeps the
start with the lowest negative log posterior, and builds the posterior in
the network's families from the fit's Gauss-Newton Hessian ``H``. The evidence is a list of
terms (:class:`~hkpd.conditioning.EvidenceTerm`): the keypoints' :class:`KeypointTerm`, then
any ``extra_terms``; the Laplace step reads only ``H`` and the fitted state, so it counts every
term's evidence without knowing the terms:

- the global rotation and camera are fixed at the fit in the samples (they vary pose and shape
  only, as they do for the network's own distribution); the pose and shape precisions either
  condition on them (``EvidenceConfig.rigid_spread="conditional"``) or marginalise them, for
  the shape Gaussian only (``"shape"``, the default: height may then trade off against the
  camera's scale) or for the joints too (``"marginal"``), by a Schur complement;
- each joint's matrix-Fisher has the fitted rotation as its mode and, as its curvature, the
  joint's precision given the other joints (``EvidenceConfig.joint_spread="conditional"``, the
  diagonal block of ``H``) or its marginal precision (``"marginal"``,
  :func:`hkpd.conditioning.laplace.marginal_precisions`);
- the shape Gaussian has the fitted shape as its mean and the marginal standard deviations.

Nothing here raises for a failed fit: a :class:`KeypointFit` without ``conditioned`` says why
(too few keypoints, non-finite numbers), and the caller falls back to the network's posterior.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import torch

from hkpd.body import BodyModel
from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.evidence_reach import untempered_unread_joints
from hkpd.conditioning.evidence_term import EvidenceTerm
from hkpd.conditioning.facing import facing_starts
from hkpd.conditioning.fit_objective import FitObjective
from hkpd.conditioning.fit_state import CAMERA, GLOBAL, NUM_BODY_JOINTS, POSE, SHAPE
from hkpd.conditioning.keypoint_evidence import KeypointEvidence
from hkpd.conditioning.keypoint_term import KeypointTerm
from hkpd.conditioning.laplace import marginal_precisions, matrix_fisher_from_precision
from hkpd.conditioning.levenberg_marquardt import SolverResult, levenberg_marquardt
from hkpd.conditioning.shape_prior import ShapeGaussian
from hkpd.distributions import BodyDistribution


@dataclass(frozen=True)
class KeypointFit:
    """The outcome of one photo's fit.

    Attributes:
        conditioned: the posterior's parameters, or None when the fit failed or was skipped.
        reason: why ``conditioned`` is None ("" when it is not).
        evidence_count: number of evidence keypoints.
        start: index of the given start that won (-1 when the fit did not run).
        turned: the winner is that start turned 180° about the body's vertical axis
            (:mod:`hkpd.conditioning.facing`), not the start as given.
        costs: ``(B + T,)`` final negative log posterior of each fitted start: the ``B``
            given ones, then the ``T`` half-turned copies that were fitted (None when the fit
            did not run); :attr:`cost` is the winner's, row :attr:`row`.
        initial_costs: ``(B + T,)`` the fitted starts' costs before the fit.
        row: the winning row of ``costs`` (-1 when the fit did not run).
        turned_initial_costs: ``(B,)`` each given start's half-turned copy's cost before the
            fit; a copy is fitted only when its cost is below every given start's
            (:func:`hkpd.conditioning.facing.facing_starts`). None with
            ``EvidenceConfig.facings`` 1 or when the fit did not run.
        iterations: Levenberg-Marquardt iterations run.
        converged: the winning start met the tolerance within the iteration limit.
        keypoint_weights: ``(17,)`` robust weights of the winning start's keypoints (1 = fully
            trusted, near 0 = treated as a detector outlier; 0 where there is no evidence).
        seconds: wall time of the fit.
        terms: names of the evidence terms the fit weighed (``("keypoints",)`` without extra
            terms; empty when it did not run).
        shape_covariance: ``(K, K)`` the posterior's full shape covariance (``shape_std`` is
            the root of its diagonal); None when the fit did not run.
        log_evidence: the winner's Laplace estimate of ``log p(evidence)`` under a given
            full-covariance shape prior (:class:`~hkpd.conditioning.shape_prior.ShapeGaussian`,
            its ``log_weight`` included), up to a constant shared by fits with the same terms
            and network reading: ``log_weight - cost + ½ log det P_shape - ½ log det H``. NaN
            without such a prior or when the fit did not run.
    """

    conditioned: BodyDistribution | None
    reason: str
    evidence_count: int
    start: int = -1
    turned: bool = False
    costs: torch.Tensor | None = None
    initial_costs: torch.Tensor | None = None
    row: int = -1
    turned_initial_costs: torch.Tensor | None = None
    iterations: int = 0
    converged: bool = False
    keypoint_weights: torch.Tensor | None = None
    seconds: float = 0.0
    terms: tuple[str, ...] = ()
    shape_covariance: torch.Tensor | None = None
    log_evidence: float = math.nan

    def __repr__(self) -> str:
        """One line of at most 200 characters: succeeded or why not, the winning start, the
        terms and the solver's figures (never the tensors: the default repr was 5.7 kB)."""
        if self.conditioned is None:
            reason = self.reason if len(self.reason) <= 120 else self.reason[:119] + "…"
            return f"KeypointFit(failed: {reason!r}, evidence_count={self.evidence_count})"
        text = (
            f"KeypointFit(succeeded, start={self.start}{', turned' if self.turned else ''}, "
            f"terms={self.terms}, evidence_count={self.evidence_count}, "
            f"iterations={self.iterations}, converged={self.converged}, cost={self.cost:.5g}, "
            f"seconds={self.seconds:.3f})"
        )
        return text if len(text) <= 200 else text[:198] + "…)"

    @property
    def succeeded(self) -> bool:
        return self.conditioned is not None

    @property
    def cost(self) -> float:
        """The winning start's final negative log posterior (NaN when the fit did not run)."""
        if self.costs is None or self.row < 0:
            return math.nan
        return float(self.costs[self.row])


def fit_evidence(
    body: BodyModel,
    starts: BodyDistribution,
    terms: Sequence[EvidenceTerm],
    config: EvidenceConfig,
    shape_prior: ShapeGaussian | None = None,
) -> SolverResult:
    """Run the fit from every start (see :func:`condition_on_keypoints`).

    Args:
        body: float64 body model.
        starts: B network predictions; each start is regularised by its own prior.
        terms: the evidence terms (e.g. ``[KeypointTerm(evidence, config)]``).
        config: the evidence settings.
        shape_prior: B full-covariance shape priors instead of the network's.
    """
    objective = FitObjective(body, starts, terms, config, shape_prior)
    result = levenberg_marquardt(
        objective,
        objective.start(),
        max_iterations=config.max_iterations,
        tolerance=config.tolerance,
    )
    if config.unread_joint_weight == config.prior_weight:
        return result
    return untempered_unread_joints(objective, result)


def laplace_posterior(
    result: SolverResult,
    start: int,
    spread: str = "conditional",
    rigid_spread: str = "conditional",
) -> tuple[BodyDistribution, torch.Tensor]:
    """The family posterior of one start from the fit's Hessian (see the module docstring),
    and its full ``(K, K)`` shape covariance.

    Args:
        result: the fit.
        start: which start's estimate and Hessian.
        spread: ``EvidenceConfig.joint_spread``.
        rigid_spread: ``EvidenceConfig.rigid_spread``: the global rotation and camera held
            fixed (``"conditional"``), marginalised for the shape Gaussian only (``"shape"``),
            or for the shape and the joints (``"marginal"``).
    """
    hessian = result.hessian[start]
    given_rigid = pose_shape_precision(hessian, "conditional")
    free_rigid = given_rigid if rigid_spread == "conditional" else None
    if free_rigid is None:
        free_rigid = pose_shape_precision(hessian, "marginal")
    joints_from = free_rigid if rigid_spread == "marginal" else given_rigid
    if spread == "marginal":
        joint_precision = marginal_precisions(joints_from, NUM_BODY_JOINTS)
    else:
        spans = [slice(3 * joint, 3 * joint + 3) for joint in range(NUM_BODY_JOINTS)]
        joint_precision = torch.stack([joints_from[span, span] for span in spans])
    state = result.state
    body_pose = state.body_pose()[start]
    F = matrix_fisher_from_precision(body_pose, joint_precision)
    shape_covariance = torch.linalg.inv(free_rigid)[POSE.stop :, POSE.stop :]
    shape_covariance = 0.5 * (shape_covariance + shape_covariance.T)
    distribution = BodyDistribution(
        F=F,
        shape_mean=state.betas[start],
        shape_std=shape_covariance.diagonal().clamp_min(0.0).sqrt(),
        global_orient=state.global_orient()[start],
        camera=state.camera()[start],
    )
    return distribution, shape_covariance


def _log_evidence(result: SolverResult, row: int, shape_prior: ShapeGaussian | None) -> float:
    """Start ``row``'s Laplace log evidence under its full-covariance shape prior (NaN
    without one): ``log_weight - cost + ½ log det P_shape - ½ log det H``, every other
    normaliser being shared by fits that differ only in the shape prior."""
    if shape_prior is None or not bool(torch.isfinite(result.cost[row])):
        return math.nan
    sign, log_det_hessian = torch.linalg.slogdet(result.hessian[row])
    if sign <= 0:
        return math.nan
    prior = shape_prior.rows(row)
    value = (
        prior.log_weight[0]
        - result.cost[row]
        + 0.5 * prior.log_det_precision()[0].to(result.cost)
        - 0.5 * log_det_hessian
    )
    return float(value)


def pose_shape_precision(hessian: torch.Tensor, rigid_spread: str) -> torch.Tensor:
    """``(69 + K, 69 + K)`` precision of pose and shape from the fit's ``(85, 85)`` Hessian.

    ``"conditional"``: the pose-and-shape block, the precision given the global rotation and
    camera. Otherwise its Schur complement ``H_kk - H_kr H_rr⁻¹ H_rk`` (``r`` the global
    rotation and camera), the precision with them marginalised (the inverse of the
    pose-and-shape block of ``H⁻¹``).
    """
    kept = torch.cat((torch.arange(POSE.start, POSE.stop), torch.arange(SHAPE.start, SHAPE.stop)))
    block = hessian[kept][:, kept]
    if rigid_spread == "conditional":
        return block
    rigid = torch.arange(GLOBAL.start, CAMERA.stop)
    coupling = hessian[kept][:, rigid]
    schur = block - coupling @ torch.linalg.solve(hessian[rigid][:, rigid], coupling.T)
    return 0.5 * (schur + schur.T)


def condition_on_keypoints(
    body: BodyModel,
    starts: BodyDistribution,
    evidence: KeypointEvidence,
    config: EvidenceConfig | None = None,
    extra_terms: Sequence[EvidenceTerm] = (),
    shape_prior: ShapeGaussian | None = None,
) -> KeypointFit:
    """Fit the body to the evidence from every start and return the conditioned posterior.

    Args:
        body: float64 body model (``BodyModel().double()``).
        starts: B >= 1 network predictions (priors and starting points); with
            ``config.facings`` 2 each may also be fitted turned 180° about the body's vertical
            axis.
        evidence: the observed keypoints in the crop the starts' cameras refer to.
        config: the evidence settings (defaults: :class:`EvidenceConfig`).
        extra_terms: evidence beyond the keypoints (:class:`EvidenceTerm`), weighed in the same
            fit and the same Laplace step; its names must differ from ``"keypoints"``.
        shape_prior: B full-covariance shape priors replacing the network's (one sex's
            population and stated measurements: :mod:`hkpd.conditioning.shape_prior`); the
            fit's ``log_evidence`` then compares such priors.

    Returns:
        A :class:`KeypointFit`; ``conditioned`` is None (with ``reason``) when there were fewer
        than ``config.min_keypoints`` evidence keypoints or the numbers were not finite.
    """
    config = config or EvidenceConfig()
    began = time.perf_counter()
    count = evidence.count
    if count < config.min_keypoints:
        return KeypointFit(
            None,
            f"only {count} keypoint(s) are evidence (confident and not under an occluder); "
            f"the fit needs at least {config.min_keypoints}",
            count,
        )
    starts64 = starts.to(torch.float64)
    if not all(
        torch.isfinite(t).all()
        for t in (starts64.F, starts64.shape_mean, starts64.shape_std, starts64.camera)
    ):
        return KeypointFit(None, "the network's prediction is not finite", count)
    with torch.no_grad():
        terms = (KeypointTerm(evidence, config), *extra_terms)
        chosen = facing_starts(body, starts64, terms, config, shape_prior)
        result = fit_evidence(body, chosen.starts, terms, config, chosen.shape_prior)
        costs = torch.where(torch.isfinite(result.cost), result.cost, torch.inf)
        best = int(costs.argmin())  # the first of equal costs: the start as given
        conditioned, shape_covariance = (
            laplace_posterior(result, best, config.joint_spread, config.rigid_spread)
            if torch.isfinite(costs[best])
            else (None, None)
        )
        log_evidence = _log_evidence(result, best, chosen.shape_prior)
    common = {
        "evidence_count": count,
        "start": chosen.origin(best)[0],
        "turned": chosen.origin(best)[1],
        "row": best,
        "turned_initial_costs": chosen.turned_initial_costs,
        "costs": result.cost,
        "initial_costs": result.initial_cost,
        "iterations": result.iterations,
        "converged": bool(result.converged[best]),
        "keypoint_weights": result.robust_weights[KeypointTerm.name][best]
        * evidence.observed.to(torch.float64),
        "terms": tuple(term.name for term in terms),
        "seconds": time.perf_counter() - began,
        "shape_covariance": shape_covariance,
        "log_evidence": log_evidence,
    }
    if conditioned is None or not conditioned.is_finite():
        return KeypointFit(None, "the fit produced non-finite numbers", **common)
    return KeypointFit(conditioned, "", **common)

"""Which joints the evidence reads: the prior of a joint no evidence term reads counts in full.

The fit tempers the network's log-density by ``EvidenceConfig.prior_weight`` (``w``, 0.5 for
the shipped network): the network read the same keypoints from its heatmaps that the fit then
weighs again, so at face value they would count twice, and the network is over-confident on
photos. Neither reason holds for a joint whose rotation moves no evidence residual (every
keypoint and hand or foot landmark below it is hidden under an occluder, unconfident or
missing): the network did not see those keypoints either, and nothing in the fit pulls on it.
Tempered, such a joint's posterior is its network reading widened by ``1/sqrt(w)`` (1.41× at
0.5): a box over a forearm made the hand look less sure with the evidence (31.7 cm) than from
the network alone (24.5 cm; issue 58). :func:`unread_joints` finds those joints at the fitted
state, and :func:`untempered_unread_joints` gives them ``EvidenceConfig.unread_joint_weight``
(1: the network's own spread) in the Laplace step's Hessian. The fit itself is unchanged (the
fitted body, its cost and every other joint's spread), so this changes what the posterior says
of the joints nothing reads and nothing else.
"""

from __future__ import annotations

from dataclasses import replace

import torch

from hkpd.conditioning.fit_objective import FitObjective
from hkpd.conditioning.fit_state import NUM_BODY_JOINTS, NUM_PARAMETERS, POSE, FitState
from hkpd.conditioning.levenberg_marquardt import SolverResult

READ_STEP = 1e-6
"""Radians each joint is turned by, about each axis, to measure what reads it."""
READ_FRACTION = 0.01
"""A joint is unread when the evidence adds less than this fraction of the network's own
information about its rotation, in every direction. On the shipped photo (issue 58) a hidden
forearm's joints get 0 and its shoulder 0.006 (the shoulder keypoint's skin turns a little with
the upper arm); joints the evidence sees get 0.02 (ankles, from the heel and toe landmarks)
to 19; the finger and toe joints, whose network concentrations are in the thousands, 0.001."""


def joint_information(
    objective: FitObjective, state: FitState
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(B, 23, 3, 3)`` each joint's information about its rotation from the evidence,
    ``E_j = J_jᵀ J_j`` (``J_j`` the evidence residuals' response to it, robust weights 1), and
    from the tempered prior, ``w P_j``, at ``state`` (leading dim ``(B,)``): each joint turned
    by :data:`READ_STEP` about each axis, in one batched evaluation (69 + 1 bodies per start,
    the cost of one Levenberg-Marquardt iteration)."""
    batch = state.betas.shape[0]
    count = POSE.stop - POSE.start
    steps = torch.zeros(count + 1, batch, NUM_PARAMETERS, dtype=state.betas.dtype)
    index = torch.arange(POSE.start, POSE.stop)
    steps[index - POSE.start + 1, :, index] = READ_STEP
    evaluated = objective(state.retract(steps.to(state.betas.device)))
    evidence = torch.cat([values.flatten(2) for values in evaluated.evidence], dim=-1)
    evidence_jacobian = _joint_blocks((evidence[1:] - evidence[:1]) / READ_STEP)
    prior = evaluated.priors[..., POSE]
    prior_jacobian = _joint_blocks((prior[1:] - prior[:1]) / READ_STEP)  # (B, 23, 69, 3)
    information = evidence_jacobian.transpose(-1, -2) @ evidence_jacobian
    tempered = prior_jacobian.transpose(-1, -2) @ prior_jacobian
    return information, tempered


def unread_joints(
    information: torch.Tensor, tempered: torch.Tensor, prior_weight: float
) -> torch.Tensor:
    """``(B, 23)`` bool: the joints the evidence reads less than :data:`READ_FRACTION` of the
    network's own information ``P_j = tempered / w`` in every direction (largest generalised
    eigenvalue of ``E_j`` against ``P_j``; ``information``, ``tempered`` from
    :func:`joint_information`). Tempered, such a joint's posterior ``w P_j + E_j`` would be
    less sure than the network's ``P_j`` whichever way it turns, with nothing the evidence
    says to show for it."""
    jitter = 1e-12 * torch.eye(3, dtype=tempered.dtype, device=tempered.device)
    root = torch.linalg.cholesky(tempered + jitter)
    relative = torch.linalg.solve_triangular(root, information, upper=False)
    relative = torch.linalg.solve_triangular(root, relative.transpose(-1, -2), upper=False)
    largest = torch.linalg.eigvalsh(0.5 * (relative + relative.transpose(-1, -2)))[..., -1]
    return largest * prior_weight < READ_FRACTION


def untempered_unread_joints(objective: FitObjective, result: SolverResult) -> SolverResult:
    """``result`` whose Hessian counts the prior of every joint the evidence does not read
    (:func:`unread_joints`, at the fitted state) at ``config.unread_joint_weight`` instead of
    the fit's ``prior_weight``: that joint's block gains ``(u / w - 1) w P_j``. Estimate,
    costs and every other entry are the fit's."""
    config = objective.prior.config
    information, tempered = joint_information(objective, result.state)
    unread = unread_joints(information, tempered, config.prior_weight)
    if not bool(unread.any()):
        return result
    gain = config.unread_joint_weight / config.prior_weight - 1.0
    extra = gain * tempered * unread[..., None, None].to(tempered)
    hessian = result.hessian.clone()
    for joint in range(NUM_BODY_JOINTS):
        block = slice(POSE.start + 3 * joint, POSE.start + 3 * joint + 3)
        hessian[:, block, block] += extra[:, joint]
    return replace(result, hessian=hessian)


def _joint_blocks(jacobian: torch.Tensor) -> torch.Tensor:
    """``(B, 23, M, 3)``: the ``(69, B, M)`` responses to each joint's three turns."""
    count, batch, rows = jacobian.shape
    blocks = jacobian.permute(1, 2, 0).reshape(batch, rows, count // 3, 3)
    return blocks.permute(0, 2, 1, 3)

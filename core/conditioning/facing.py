"""The two facings of a start: as the network read it, and turned half about the body's up axis.

A 2D keypoint detector tells a person's left from right, and so whether the person faces the
camera (left shoulder to the right of the right one in the photo, for an upright person) or is
seen from behind. The network may read a person seen from behind as facing the camera; a fit
started there cannot turn the body round against the global rotation's prior (0.5 rad) and
ends sideways with the limbs bent instead. So the fit
also starts from each start with its global rotation composed with a half turn about the
body's vertical axis, ``R_g' = R_g · diag(-1, 1, -1)`` (SMPL's Y is up, +Z forward): the
same relative pose, shape and camera, the body turned on the spot about its root, and its own
global-rotation prior centred there. The left/right assignment of the keypoints stays, as the
detector made it. Whichever start ends with the lower negative log posterior wins
(:func:`hkpd.conditioning.condition_on_keypoints`; ``docs/evidence.md``, "Facing").

A half-turned copy is fitted only when it explains the evidence better *before* the fit than
every start as given (:func:`facing_starts`): its cost at its own prior's mode (where every
prior residual is zero, so the two costs differ by the keypoints' misfit alone) is lower. On
100 synthetic test examples the turned copy won 2 fits, both of them kept by this rule, which
fitted a copy in those 2 only; on ``coco_mini``'s photos it fitted none, so a photo's fit costs
one more cost evaluation, not a second fit.

This does not help where the detector's own labels point the wrong way (issue 42's cook,
``coco_mini`` val2017 ``000000397133.jpg``, is labelled as if he faced the camera): the fit
follows the labels, and under the weak-perspective camera no facing explains swapped labels
better (``docs/evidence.md``, "Facing").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import torch

from hkpd.body import BodyModel
from hkpd.conditioning.config import EvidenceConfig
from hkpd.conditioning.evidence_term import EvidenceTerm
from hkpd.conditioning.fit_objective import FitObjective
from hkpd.conditioning.fit_state import NUM_PARAMETERS
from hkpd.conditioning.levenberg_marquardt import robust_cost
from hkpd.conditioning.shape_prior import ShapeGaussian
from hkpd.distributions import BodyDistribution

HALF_TURN_ABOUT_UP = torch.tensor([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
"""``(3, 3)`` a half turn about the body frame's up axis (SMPL Y), applied before the global
rotation."""


def half_turned(starts: BodyDistribution) -> BodyDistribution:
    """``starts`` turned 180° about each body's own vertical axis (``R_g · HALF_TURN_ABOUT_UP``);
    pose, shape and camera unchanged."""
    turn = HALF_TURN_ABOUT_UP.to(starts.global_orient)
    return replace(starts, global_orient=starts.global_orient @ turn)


@dataclass(frozen=True)
class FacingStarts:
    """The fit's starts for one photo.

    Attributes:
        starts: ``(B + T,)`` the ``B`` starts as given, then the ``T`` half-turned copies
            worth fitting.
        turned_from: ``T`` entries: the given start each half-turned copy was made from.
        turned_initial_costs: ``(B,)`` every half-turned copy's cost before the fit (None with
            ``EvidenceConfig.facings`` 1).
        shape_prior: the full-covariance shape prior of each row of ``starts`` (a turned copy
            has its origin's), or None when the fit uses the network's.
    """

    starts: BodyDistribution
    turned_from: tuple[int, ...]
    turned_initial_costs: torch.Tensor | None
    shape_prior: ShapeGaussian | None = None

    def origin(self, row: int) -> tuple[int, bool]:
        """The given start that fitted start ``row`` came from, and whether it is turned."""
        given = self.starts.camera.shape[0] - len(self.turned_from)
        return (row, False) if row < given else (self.turned_from[row - given], True)


def initial_costs(
    body: BodyModel,
    starts: BodyDistribution,
    terms: Sequence[EvidenceTerm],
    config: EvidenceConfig,
    shape_prior: ShapeGaussian | None = None,
) -> torch.Tensor:
    """``(B,)`` the fit's cost of each start at its own prior's mode (float64 ``starts``)."""
    objective = FitObjective(body, starts, terms, config, shape_prior)
    state = objective.start()
    still = torch.zeros(1, *state.betas.shape[:-1], NUM_PARAMETERS, dtype=state.betas.dtype)
    return robust_cost(objective(state.retract(still)), objective.robust_scales())[0]


def facing_starts(
    body: BodyModel,
    starts: BodyDistribution,
    terms: Sequence[EvidenceTerm],
    config: EvidenceConfig,
    shape_prior: ShapeGaussian | None = None,
) -> FacingStarts:
    """The ``B`` starts as given and, with ``config.facings`` 2, the half-turned copies whose
    cost before the fit is below that of every start as given (the module docstring);
    ``shape_prior`` (B rows) follows the starts."""
    if config.facings == 1:
        return FacingStarts(starts, (), None, shape_prior)
    turned = half_turned(starts)
    both_priors = None if shape_prior is None else shape_prior.concatenated(shape_prior)
    costs = initial_costs(body, concatenated(starts, turned), terms, config, both_priors)
    given = starts.camera.shape[0]
    turned_costs = costs[given:]
    chosen = (turned_costs < costs[:given].min()).nonzero().flatten()
    fitted = concatenated(starts, turned.rows(chosen))
    fitted_priors = (
        None if shape_prior is None else shape_prior.concatenated(shape_prior.rows(chosen))
    )
    return FacingStarts(fitted, tuple(int(i) for i in chosen), turned_costs, fitted_priors)


def concatenated(first: BodyDistribution, second: BodyDistribution) -> BodyDistribution:
    """``first``'s rows, then ``second``'s."""
    pairs = zip(first.tensors(), second.tensors(), strict=True)
    return BodyDistribution(*(torch.cat(pair) for pair in pairs))


def faces_camera(global_orient: torch.Tensor) -> torch.Tensor:
    """``(...)`` bool: the body's forward axis (body +Z) points towards the camera, i.e. its
    camera-frame z component (the camera looks along +z) is negative; ``global_orient (..., 3,
    3)`` maps body axes to the camera's."""
    return global_orient[..., 2, 2] < 0

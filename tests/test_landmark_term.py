"""The hand and foot landmark term: exact landmarks recover the wrists' and ankles' rotations
that the keypoints leave to the prior, the Laplace step narrows them, and a landmark that is
not evidence (e.g. under a box) changes nothing."""

from __future__ import annotations

import math

import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES, extremity_landmarks
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, KeypointFit, condition_on_keypoints
from hkpd.conditioning.landmark_term import LandmarkConfig, LandmarkEvidence, LandmarkTerm
from hkpd.distributions import BodyDistribution

SIZE = 256
EXTREMITY_ROWS = (19, 20, 6, 7)
"""``body_pose`` rows of the left and right wrist and ankle."""
EXACT = LandmarkConfig(hand_sigma_scale=0.25, foot_sigma_scale=0.25)
"""Sigmas for exact landmarks (about 2 px on a 256-pixel crop)."""


@pytest.fixture(scope="module")
def body64() -> BodyModel:
    return BodyModel().double()


def problem(body64: BodyModel, seed: int) -> tuple[torch.Tensor, BodyDistribution, dict]:
    """A body turned 40° from the camera with its wrists and ankles turned 45° about random
    axes; a vague start (concentration 3) 15° off at those joints, on the truth's side of the
    depth flip (the mirror image across the image plane that 2D points cannot tell apart).
    Returns the true pose, the start and the exact keypoints and landmarks (crop pixels)."""
    generator = torch.Generator().manual_seed(seed)
    pose = roma.rotvec_to_rotmat(0.25 * torch.randn(23, 3, generator=generator).double())
    start = pose.clone()
    for row in EXTREMITY_ROWS:
        axis = torch.nn.functional.normalize(torch.randn(3, generator=generator).double(), dim=0)
        pose[row] = roma.rotvec_to_rotmat(axis * math.radians(45))
        axis = torch.nn.functional.normalize(torch.randn(3, generator=generator).double(), dim=0)
        start[row] = pose[row] @ roma.rotvec_to_rotmat(axis * math.radians(15))
    turn = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.7, 0.0], dtype=torch.float64))
    orient = turn @ FRONTAL_GLOBAL_ORIENT.double()
    betas = torch.zeros(1, 10, dtype=torch.float64)
    posed = body64(betas, pose[None], orient[None])
    camera = torch.tensor([0.9, 0.0, 0.1], dtype=torch.float64)
    root = posed.joints[0, :1]

    def pixels(points: torch.Tensor) -> torch.Tensor:
        return ndc_to_pixels(camera[0] * ((points - root)[:, :2] + camera[1:]), SIZE)

    regressor = extremity_landmarks(body64).rows(BLAZEPOSE_EXTREMITY_NAMES)
    concentration = torch.full((23, 3, 1), 40.0, dtype=torch.float64)
    concentration[list(EXTREMITY_ROWS)] = 3.0
    starts = BodyDistribution(
        F=(concentration * start)[None],
        shape_mean=torch.zeros(1, 10, dtype=torch.float64),
        shape_std=torch.ones(1, 10, dtype=torch.float64),
        global_orient=orient[None],
        camera=camera[None].clone(),
    )
    observed = {
        "keypoints": pixels(posed.keypoints[0]),
        "landmarks": pixels(regressor.of_mesh(posed.vertices)[0]),
        "regressor": regressor,
    }
    return pose, starts, observed


def fit(body64, starts, observed, shown: torch.Tensor | None) -> KeypointFit:
    """The fit on the exact keypoints, and on the landmarks ``shown`` (None: no landmark term)."""
    config = EvidenceConfig()
    keypoints = KeypointEvidence(observed["keypoints"], torch.ones(17, dtype=torch.bool), SIZE)
    terms = []
    if shown is not None:
        evidence = LandmarkEvidence(observed["landmarks"], shown, SIZE)
        terms = [
            LandmarkTerm(
                evidence, observed["regressor"], config.keypoint_sigma, config.robust_scale, EXACT
            )
        ]
    result = condition_on_keypoints(body64, starts, keypoints, config, terms)
    assert result.conditioned is not None
    return result


def mode_and_concentration(result: KeypointFit) -> tuple[torch.Tensor, torch.Tensor]:
    """``(23, 3, 3)`` modal rotations and ``(23,)`` mean singular values of the posterior."""
    F = result.conditioned.F.reshape(23, 3, 3)
    U, S, Vh = torch.linalg.svd(F)
    D = torch.ones_like(S)
    D[:, -1] = torch.det(U @ Vh)
    return U @ torch.diag_embed(D) @ Vh, S.mean(-1)


def angles(mode: torch.Tensor, pose: torch.Tensor) -> list[float]:
    return [
        math.degrees(float(roma.rotmat_geodesic_distance(mode[row], pose[row])))
        for row in EXTREMITY_ROWS
    ]


@pytest.mark.parametrize("seed", [4, 7])
def test_exact_landmarks_recover_wrists_and_ankles(body64, seed: int) -> None:
    pose, starts, observed = problem(body64, seed)
    without, spread_without = mode_and_concentration(fit(body64, starts, observed, None))
    shown = torch.ones(10, dtype=torch.bool)
    with_landmarks, spread_with = mode_and_concentration(fit(body64, starts, observed, shown))
    assert min(angles(without, pose)) > 14.0  # the keypoints leave them where the start was
    assert max(angles(with_landmarks, pose)) < 10.0
    rows = list(EXTREMITY_ROWS)
    assert (spread_with[rows] > 10 * spread_without[rows]).all()  # and the Laplace step narrows


def test_a_landmark_that_is_not_evidence_changes_nothing(body64) -> None:
    _, starts, observed = problem(body64, 4)
    shown = torch.ones(10, dtype=torch.bool)
    shown[6] = False  # the left heel, e.g. under an occluder
    first = fit(body64, starts, observed, shown)
    moved = dict(observed, landmarks=observed["landmarks"].clone())
    moved["landmarks"][6] += torch.tensor([60.0, -40.0], dtype=torch.float64)
    second = fit(body64, starts, moved, shown)
    for a, b in zip(first.conditioned.tensors(), second.conditioned.tensors(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert first.terms == ("keypoints", "landmarks")
    # and the heel's evidence, when shown, does move the fit
    third = fit(body64, starts, moved, torch.ones(10, dtype=torch.bool))
    assert not torch.equal(third.conditioned.F, first.conditioned.F)


def test_term_checks_its_inputs(body64) -> None:
    regressor = extremity_landmarks(body64).rows(BLAZEPOSE_EXTREMITY_NAMES)
    with pytest.raises(ValueError, match="expected landmarks"):
        LandmarkEvidence(torch.zeros(10, 3), torch.ones(10, dtype=torch.bool), SIZE)
    evidence = LandmarkEvidence(torch.zeros(6, 2), torch.ones(6, dtype=torch.bool), SIZE)
    with pytest.raises(ValueError, match="6 detected landmarks for a regressor of 10"):
        LandmarkTerm(evidence, regressor, 0.03, 3.0)
    with pytest.raises(ValueError, match="hand_sigma_scale"):
        LandmarkConfig(hand_sigma_scale=0.0)

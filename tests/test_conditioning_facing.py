"""Both facings of the fit (issue 42): a body seen from behind is fitted facing away."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import (
    EvidenceConfig,
    KeypointEvidence,
    condition_on_keypoints,
    faces_camera,
    half_turned,
)
from hkpd.conditioning.facing import HALF_TURN_ABOUT_UP, facing_starts
from hkpd.conditioning.keypoint_term import KeypointTerm
from hkpd.distributions import BodyDistribution, KinematicMatrixFisher
from hkpd.kinematic_tree import BODY_PARENTS

SIZE = 128
COOK_PHOTO = Path("/work/shared/data/coco_mini/val2017/000000397133.jpg")


@pytest.fixture(scope="module")
def body64() -> BodyModel:
    return BodyModel().double()


def _project(body, pose, orient, camera, betas) -> torch.Tensor:
    keypoints, joints = body.posed_keypoints(betas, pose[None], orient[None])
    relative = keypoints[0] - joints[0, :1]
    return ndc_to_pixels(camera[0] * (relative[:, :2] + camera[1:]), SIZE)


@pytest.fixture(scope="module")
def seen_from_behind(body64):
    """A standing body turned away from the camera, its exact keypoints, and a start that
    reads the same pose facing the camera (as the network reads most people)."""
    generator = torch.Generator().manual_seed(5)
    pose = roma.rotvec_to_rotmat(0.25 * torch.randn(23, 3, generator=generator).double())
    away = FRONTAL_GLOBAL_ORIENT.double() @ HALF_TURN_ABOUT_UP.double()
    camera = torch.tensor([0.95, 0.02, 0.05], dtype=torch.float64)
    betas = 0.5 * torch.randn(1, 10, generator=generator).double()
    keypoints = _project(body64, pose, away, camera, betas)
    offset = roma.rotvec_to_rotmat(0.1 * torch.randn(23, 3, generator=generator).double())
    start = BodyDistribution(
        F=(10.0 * (pose @ offset))[None],
        shape_mean=torch.zeros(1, 10).double(),
        shape_std=torch.ones(1, 10).double(),
        global_orient=FRONTAL_GLOBAL_ORIENT.double()[None],
        camera=torch.tensor([[0.9, 0.0, 0.0]]).double(),
    )
    evidence = KeypointEvidence(keypoints, torch.ones(17, dtype=torch.bool), SIZE)
    return {"start": start, "evidence": evidence, "keypoints": keypoints}


def _away(global_orient: torch.Tensor) -> float:
    """Cosine between the body's forward axis and the camera's viewing direction (1: facing
    straight away from the camera, -1: facing it)."""
    return float(global_orient[2, 2])


def _reprojection(body64, fit, keypoints) -> torch.Tensor:
    c = fit.conditioned
    pose = KinematicMatrixFisher(c.F[None], BODY_PARENTS).mode[0]
    points = _project(body64, pose, c.global_orient, c.camera, c.shape_mean[None])
    return (points - keypoints).norm(dim=-1)


def test_half_turn_turns_a_frontal_body_away_and_back() -> None:
    frontal = FRONTAL_GLOBAL_ORIENT.double()
    start = BodyDistribution(
        torch.eye(3).double().expand(1, 23, 3, 3), torch.zeros(1, 10).double(),
        torch.ones(1, 10).double(), frontal[None], torch.tensor([[1.0, 0.1, 0.2]]).double(),
    )  # fmt: skip
    turned = half_turned(start)
    assert bool(faces_camera(frontal)) and not bool(faces_camera(turned.global_orient[0]))
    assert torch.allclose(half_turned(turned).global_orient, start.global_orient)
    assert torch.equal(turned.F, start.F) and torch.equal(turned.camera, start.camera)
    with pytest.raises(ValueError, match=r"EvidenceConfig\.facings"):
        EvidenceConfig(facings=0)


def test_a_half_turned_copy_is_fitted_only_where_it_explains_the_keypoints_better(
    body64, seen_from_behind
) -> None:
    scene = seen_from_behind
    terms = [KeypointTerm(scene["evidence"], EvidenceConfig())]
    facing = scene["start"]  # reads the body seen from behind as facing the camera
    away = half_turned(facing)
    quarter = roma.rotvec_to_rotmat(torch.tensor([0.0, math.pi / 2, 0.0], dtype=torch.float64))
    sideways = replace(facing, global_orient=facing.global_orient @ quarter)
    pairs = zip(facing.tensors(), sideways.tensors(), strict=True)
    starts = BodyDistribution(*(torch.cat(pair) for pair in pairs))
    chosen = facing_starts(body64, starts, terms, EvidenceConfig())
    # the copy of the facing start (turned away) beats both given starts before the fit; the
    # copy of the sideways start (sideways the other way) does not
    assert chosen.turned_from == (0,) and chosen.starts.camera.shape[0] == 3
    assert chosen.turned_initial_costs[0] < chosen.turned_initial_costs[1]
    assert chosen.origin(0) == (0, False) and chosen.origin(2) == (0, True)
    assert torch.equal(chosen.starts.global_orient[2], away.global_orient[0])
    single = facing_starts(body64, starts, terms, EvidenceConfig(facings=1))
    assert (
        single.starts is starts and single.turned_from == () and single.turned_initial_costs is None
    )
    turned_back = facing_starts(body64, away, terms, EvidenceConfig())
    assert turned_back.turned_from == () and turned_back.starts.camera.shape[0] == 1


def test_a_body_seen_from_behind_is_fitted_facing_away(body64, seen_from_behind) -> None:
    scene = seen_from_behind
    one = condition_on_keypoints(
        body64, scene["start"], scene["evidence"], EvidenceConfig(facings=1)
    )
    both = condition_on_keypoints(body64, scene["start"], scene["evidence"], EvidenceConfig())
    assert one.succeeded and both.succeeded
    # From the network's facing alone the fit cannot turn the body round (it stops at least
    # 60° short of facing away, sideways and bent to reach the keypoints) ...
    assert _away(one.conditioned.global_orient) < 0.5
    missed = _reprojection(body64, one, scene["keypoints"]).mean()
    assert missed > 1.5
    # ... from both facings the half-turned start wins, faces away and lands on the keypoints.
    assert both.turned and both.start == 0
    assert not bool(faces_camera(both.conditioned.global_orient))
    assert _away(both.conditioned.global_orient) > 0.95
    assert _reprojection(body64, both, scene["keypoints"]).mean() < 0.5 * missed
    assert both.costs.shape == (2,) and both.row == 1
    assert both.cost == pytest.approx(float(both.costs[1]))
    assert both.cost < one.cost


def test_a_body_facing_the_camera_keeps_its_fit(body64, seen_from_behind) -> None:
    scene = seen_from_behind
    start = half_turned(scene["start"])  # now the start faces the way the body does
    one = condition_on_keypoints(body64, start, scene["evidence"], EvidenceConfig(facings=1))
    both = condition_on_keypoints(body64, start, scene["evidence"], EvidenceConfig())
    assert not both.turned and both.start == 0 and both.costs.shape == (1,)  # copy not fitted
    for mine, theirs in zip(both.conditioned.tensors(), one.conditioned.tensors(), strict=True):
        assert torch.allclose(mine, theirs, rtol=0, atol=0)
    assert both.cost == pytest.approx(one.cost)


@pytest.fixture(scope="module")
def cook():
    """The shipped predictor's evidence posterior of the cook (seen from behind) and the
    detector's shoulder and hip offsets ``x(left) - x(right)``."""
    from hkpd.evaluation.real_photos import load_coco_people
    from hkpd.prediction import Predictor

    people = load_coco_people(COOK_PHOTO.parents[1], min_visible=0)
    person = next(
        p
        for p in people
        if p.image_path.name == COOK_PHOTO.name
        and p.visible[[5, 6, 11, 12]].all()
        and p.keypoints[5, 0] < p.keypoints[6, 0]
        and p.keypoints[11, 0] < p.keypoints[12, 0]
    )  # the annotators put his left shoulder and hip left of the right ones: seen from behind
    predictor = Predictor.from_pretrained(device="cpu")
    try:
        posterior = predictor.predict(person.image_path, bbox=person.search_box())
    finally:
        predictor.close()
    detected = posterior.keypoints.double().numpy()
    offsets = np.array([detected[5, 0] - detected[6, 0], detected[11, 0] - detected[12, 0]])
    return posterior, offsets


@pytest.mark.skipif(not COOK_PHOTO.is_file(), reason="coco_mini (/work/shared/data) not available")
def test_the_cook_faces_the_way_the_detector_labels_him(cook) -> None:
    posterior, offsets = cook
    fit = posterior.evidence_fit
    assert posterior.source == "evidence" and fit is not None
    # BlazePose labels the cook as facing the camera (left shoulder and hip to the right) ...
    assert (offsets > 20).all()
    # ... and the fit follows its labels: turned away, the start fits them far worse, so that
    # copy is not even fitted.
    assert not fit.turned and fit.costs.shape == (1,)
    assert float(fit.turned_initial_costs[0]) > 2 * float(fit.initial_costs[0])
    assert bool(faces_camera(posterior.global_orient.double()))
    assert not math.isnan(fit.cost)


@pytest.mark.skipif(not COOK_PHOTO.is_file(), reason="coco_mini (/work/shared/data) not available")
@pytest.mark.xfail(
    strict=True,
    reason="issue 42: the detector labels the cook's left and right as if he faced the camera; "
    "the fit keeps the detector's labels, so no start facing away explains them better",
)
def test_the_cook_is_read_seen_from_behind(cook) -> None:
    posterior, _ = cook
    assert not bool(faces_camera(posterior.global_orient.double()))


@pytest.mark.skipif(not COOK_PHOTO.is_file(), reason="coco_mini (/work/shared/data) not available")
def test_the_cook_turned_around_faces_away_and_turns_back(cook) -> None:
    posterior, _ = cook
    turned = posterior.turned_around()
    assert turned.turned and not posterior.turned
    assert not bool(faces_camera(turned.global_orient.double()))
    assert turned.turned_around() is posterior

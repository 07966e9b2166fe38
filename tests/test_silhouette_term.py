"""The silhouette term: synthetic bodies' exact masks (rasterised with the fit's own camera)
move the fit's shape towards the truth (PVE-T-SC lower on every body, girth read), a wider mask
raises girth (β₂, +20 % volume per unit in this body model), a box clears the evidence inside
it, and the surface points the term reads are the mesh's own vertices."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import (
    EvidenceConfig,
    KeypointEvidence,
    KeypointFit,
    SilhouetteConfig,
    SilhouetteEvidence,
    SilhouetteTerm,
    SurfaceSamples,
    condition_on_keypoints,
)
from hkpd.conditioning.surface_points import vertex_subset_model
from hkpd.distributions import BodyDistribution
from hkpd.evaluation.metrics import pve_t_sc_from_betas

SIZE = 256
GIRTH = 2
EXACT = SilhouetteConfig(
    outside_sigma=0.01, inside_sigma=0.02, boundary_sigma=0.05, inside_margin=0.0
)
"""Settings for an exact mask: a third of the default sigmas and no clothing margin."""


@pytest.fixture(scope="module")
def body64() -> BodyModel:
    return BodyModel().double()


_SURFACES: dict[int, SurfaceSamples] = {}


def surface_of(body: BodyModel) -> SurfaceSamples:
    """The body's surface samples, made once (as a predictor would)."""
    if id(body) not in _SURFACES:
        _SURFACES[id(body)] = SurfaceSamples.of(body)
    return _SURFACES[id(body)]


def test_surface_samples_have_outward_normals(body64) -> None:
    surface = surface_of(body64)
    assert surface.count == 400 and len(set(surface.points.tolist())) == 400
    rest = body64.v_template
    points, first, second = (rest[i] for i in (surface.points, surface.first, surface.second))
    normals = torch.linalg.cross(first - points, second - points)
    outward = ((points - rest.mean(0)) * normals).sum(-1) > 0
    assert outward.double().mean() > 0.8  # away from the centre, for all but hollows


class Problem:
    """A body (seeded pose and shape, frontal), its exact keypoints and exact mask in a 256 crop
    (weak-perspective camera, the fit's own), and a start at the mean shape."""

    def __init__(self, body: BodyModel, seed: int) -> None:
        generator = torch.Generator().manual_seed(seed)
        self.pose = roma.rotvec_to_rotmat(0.2 * torch.randn(23, 3, generator=generator).double())
        self.orient = FRONTAL_GLOBAL_ORIENT.double()
        self.betas = torch.randn(1, 10, generator=generator).double()
        self.camera = torch.tensor([0.9, 0.0, 0.1], dtype=torch.float64)
        output = body(self.betas, self.pose[None], self.orient[None])
        root = output.joints[0, :1]
        keypoints = ndc_to_pixels(self.project(output.keypoints[0] - root), SIZE)
        self.keypoints = KeypointEvidence(keypoints, torch.ones(17, dtype=torch.bool), SIZE)
        pixels = ndc_to_pixels(self.project(output.vertices[0] - root), SIZE).numpy()
        self.mask = np.zeros((SIZE, SIZE), np.uint8)
        for triangle in np.round(pixels[body.faces.numpy()] * 16).astype(np.int32):
            cv2.fillConvexPoly(self.mask, triangle, 1, cv2.LINE_8, 4)
        self.start = BodyDistribution(
            F=(20.0 * self.pose)[None],
            shape_mean=torch.zeros(1, 10, dtype=torch.float64),
            shape_std=torch.ones(1, 10, dtype=torch.float64),
            global_orient=self.orient[None],
            camera=torch.tensor([[0.85, 0.02, 0.05]], dtype=torch.float64),
        )

    def project(self, points: torch.Tensor) -> torch.Tensor:
        return self.camera[0] * (points[:, :2] + self.camera[1:])

    def fit(
        self,
        body: BodyModel,
        mask: np.ndarray | None,
        known: np.ndarray | None = None,
        config: SilhouetteConfig | None = None,
    ) -> KeypointFit:
        terms = []
        if mask is not None:
            evidence = SilhouetteEvidence.from_arrays(mask.astype(np.float64), known)
            terms = [SilhouetteTerm(evidence, surface_of(body), config or EXACT)]
        return condition_on_keypoints(body, self.start, self.keypoints, EvidenceConfig(), terms)


@pytest.fixture(scope="module")
def problem(body64) -> Problem:
    return Problem(body64, seed=3)


def test_surface_points_are_the_mesh_vertices(body64, problem) -> None:
    index = torch.tensor([0, 17, 3000, body64.num_vertices - 1])
    subset = vertex_subset_model(body64, index)
    pose, orient = problem.pose[None], problem.orient[None]
    whole = body64(problem.betas, pose, orient)
    part = subset(problem.betas, pose, orient)
    torch.testing.assert_close(part.vertices, whole.vertices[:, index], rtol=0, atol=1e-12)
    torch.testing.assert_close(part.joints, whole.joints, rtol=0, atol=1e-12)


def test_exact_masks_move_the_shape_towards_the_truth(body64, problem) -> None:
    problems = [problem, *(Problem(body64, seed) for seed in range(4, 9))]
    errors: dict[str, list[torch.Tensor]] = {"plain": [], "seen": []}
    shape_error: dict[str, list[torch.Tensor]] = {"plain": [], "seen": []}
    for case in problems:
        for name, mask in (("plain", None), ("seen", case.mask)):
            fit = case.fit(body64, mask)
            assert fit.succeeded and fit.terms[-1] == (
                "silhouette" if name == "seen" else "keypoints"
            )
            predicted = fit.conditioned.shape_mean[None]
            errors[name].append(pve_t_sc_from_betas(body64, predicted, case.betas)[0])
            shape_error[name].append((predicted - case.betas)[0].abs())
    plain_pve, seen_pve = torch.stack(errors["plain"]), torch.stack(errors["seen"])
    plain_shape, seen_shape = torch.stack(shape_error["plain"]), torch.stack(shape_error["seen"])
    assert (seen_pve < plain_pve).all() and seen_pve.mean() < 0.9 * plain_pve.mean()
    assert seen_shape[:, 1:].mean() < 0.95 * plain_shape[:, 1:].mean()
    assert seen_shape[:, GIRTH].mean() < 0.6 * plain_shape[:, GIRTH].mean()  # girth is read


def test_a_wider_mask_raises_girth(body64, problem) -> None:
    exact = problem.fit(body64, problem.mask)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    wider = problem.fit(body64, cv2.dilate(problem.mask, disc))
    assert wider.conditioned.shape_mean[GIRTH] > exact.conditioned.shape_mean[GIRTH] + 0.2


def test_a_box_clears_the_mask_evidence_inside_it(body64, problem) -> None:
    known = np.ones((SIZE, SIZE), dtype=bool)
    rows, columns = np.nonzero(problem.mask)
    top, left = int(rows.mean()), int(columns.mean())  # over the belly
    known[top - 20 : top + 20, left - 25 : left + 25] = False
    changed = problem.mask.copy()
    changed[top - 20 : top + 20, left - 25 : left + 25] = 0  # a hole, only inside the box
    first = problem.fit(body64, problem.mask, known)
    second = problem.fit(body64, changed, known)
    for mine, theirs in zip(first.conditioned.tensors(), second.conditioned.tensors(), strict=True):
        assert torch.equal(mine, theirs)
    # without the box, the hole is evidence and moves the fit
    holed = problem.fit(body64, changed)
    assert not torch.equal(holed.conditioned.shape_mean, first.conditioned.shape_mean)


def test_the_term_is_surer_of_girth(body64, problem) -> None:
    plain, seen = problem.fit(body64, None), problem.fit(body64, problem.mask)
    assert seen.conditioned.shape_std[GIRTH] < 0.7 * plain.conditioned.shape_std[GIRTH]


def test_residuals_are_zero_where_nothing_is_known(body64, problem) -> None:
    nothing = np.zeros((SIZE, SIZE), dtype=bool)
    evidence = SilhouetteEvidence.from_arrays(problem.mask.astype(np.float64), nothing)
    term = SilhouetteTerm(evidence, surface_of(body64))
    assert term.boundary_count == 0
    fit = problem.fit(body64, problem.mask, nothing)
    plain = problem.fit(body64, None)
    torch.testing.assert_close(fit.conditioned.shape_mean, plain.conditioned.shape_mean)


def test_an_empty_mask_is_no_evidence(body64, problem) -> None:
    empty = np.zeros((SIZE, SIZE))
    term = SilhouetteTerm(SilhouetteEvidence.from_arrays(empty, None), surface_of(body64))
    assert term.boundary_count == 0 and not term.outside_distance.any()
    fit = problem.fit(body64, empty)
    plain = problem.fit(body64, None)
    torch.testing.assert_close(fit.conditioned.shape_mean, plain.conditioned.shape_mean)


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="outside_sigma"):
        SilhouetteConfig(outside_sigma=0.0)
    with pytest.raises(ValueError, match="maps"):
        SilhouetteEvidence(torch.zeros(4, 4), torch.ones(4, 5, dtype=torch.bool), 4)

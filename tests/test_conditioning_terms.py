"""The fit's evidence as a list of terms: the keypoint-only fit is unchanged against a reference
recorded before the terms existed, and a new term plugs in without touching the solver."""

from __future__ import annotations

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
    KeypointFit,
    KeypointTerm,
    condition_on_keypoints,
    fit_evidence,
)
from hkpd.conditioning.keypoint_fit import pose_shape_precision
from hkpd.distributions import BodyDistribution

SIZE = 160
REFERENCE = Path(__file__).parent / "data" / "keypoint_fit_reference.npz"
"""The fit of :func:`reference_problem` as the code computed it before the evidence became a
list of terms (written once by :func:`write_reference`)."""
REFERENCE_CONFIG = EvidenceConfig(rigid_spread="conditional", unread_joint_weight=0.5)
"""The settings the reference was recorded with (the Laplace step then held the global rotation
and camera fixed; ``rigid_spread`` keeps that one setting away; every joint was tempered alike,
``unread_joint_weight`` equal to the prior weight, before issue 58)."""


@pytest.fixture(scope="module")
def body64() -> BodyModel:
    return BodyModel().double()


def reference_problem(body64: BodyModel) -> tuple[BodyDistribution, KeypointEvidence]:
    """Two starts (one turned away), a body's exact keypoints with one hidden and one moved
    30 px off (an outlier the robust loss must down-weight)."""
    generator = torch.Generator().manual_seed(11)
    pose = roma.rotvec_to_rotmat(0.3 * torch.randn(23, 3, generator=generator).double())
    orient = FRONTAL_GLOBAL_ORIENT.double()
    betas = 0.6 * torch.randn(1, 10, generator=generator).double()
    keypoints, joints = body64.posed_keypoints(betas, pose[None], orient[None])
    camera = torch.tensor([0.9, 0.03, 0.08], dtype=torch.float64)
    ndc = camera[0] * ((keypoints[0] - joints[0, :1])[:, :2] + camera[1:])
    pixels = ndc_to_pixels(ndc, SIZE)
    pixels[7] += torch.tensor([30.0, -12.0], dtype=torch.float64)
    observed = torch.ones(17, dtype=torch.bool)
    observed[16] = False
    offset = roma.rotvec_to_rotmat(0.2 * torch.randn(2, 23, 3, generator=generator).double())
    concentration = 5.0 + 20.0 * torch.rand(2, 23, 3, 1, generator=generator).double()
    turned = roma.rotvec_to_rotmat(torch.tensor([0.0, 0.4, 0.3], dtype=torch.float64))
    starts = BodyDistribution(
        F=concentration * (pose @ offset),
        shape_mean=0.2 * torch.randn(2, 10, generator=generator).double(),
        shape_std=0.5 + torch.rand(2, 10, generator=generator).double(),
        global_orient=torch.stack((orient, turned @ orient)),
        camera=torch.tensor([[0.85, 0.0, 0.0], [0.95, 0.05, 0.1]], dtype=torch.float64),
    )
    return starts, KeypointEvidence(pixels, observed, SIZE)


def _fit_record(fit: KeypointFit) -> dict[str, np.ndarray]:
    """Every number of a fit report, by name."""
    assert fit.conditioned is not None
    record = {f"conditioned_{i}": t.numpy() for i, t in enumerate(fit.conditioned.tensors())}
    record.update(
        costs=fit.costs.numpy(),
        initial_costs=fit.initial_costs.numpy(),
        keypoint_weights=fit.keypoint_weights.numpy(),
        summary=np.array([fit.start, fit.iterations, fit.converged, fit.evidence_count]),
    )
    return record


def write_reference(body64: BodyModel) -> None:
    """Record today's fit of :func:`reference_problem` (run once, before a redesign)."""
    starts, evidence = reference_problem(body64)
    fit = condition_on_keypoints(body64, starts, evidence, REFERENCE_CONFIG)
    np.savez(REFERENCE, **_fit_record(fit))


def test_keypoint_only_fit_matches_the_reference(body64) -> None:
    starts, evidence = reference_problem(body64)
    fit = condition_on_keypoints(body64, starts, evidence, REFERENCE_CONFIG)
    reference = np.load(REFERENCE)
    record = _fit_record(fit)
    assert set(record) == set(reference.files)
    # Bit-identical on the machine that recorded it; another CPU's float64 kernels move the
    # iterative fit by up to ~1e-6 relative (measured 6.8e-7), far below any change of method.
    for name, value in record.items():
        np.testing.assert_allclose(value, reference[name], rtol=1e-5, atol=1e-8, err_msg=name)
    weights = record["keypoint_weights"]
    assert weights[7] < 0.5 < weights[:7].min() and weights[16] == 0.0  # outlier, hidden


class ShapePull:
    """A toy evidence term: "shape coefficient ``index`` is ``target`` ± ``sigma``"."""

    residual_shape = (1, 1)
    needs_vertices = False
    surface_vertices = None

    def __init__(self, index: int, target: float, sigma: float, robust_scale=None) -> None:
        self.name = "shape_pull"
        self.index, self.target, self.sigma = index, target, sigma
        self.robust_scale = robust_scale

    def residuals(self, posed):
        return ((posed.betas[..., self.index] - self.target) / self.sigma)[..., None, None]


class VertexProbe:
    """A toy term that asks for the vertices, checks what it gets, and adds no evidence."""

    name = "vertex_probe"
    residual_shape = (1, 1)
    robust_scale = None
    needs_vertices = True
    surface_vertices = None

    def __init__(self) -> None:
        self.shapes: list[tuple[int, ...]] = []

    def residuals(self, posed):
        self.shapes.append(tuple(posed.vertices.shape))
        return 0.0 * posed.vertices[..., :1, :1]


def test_a_new_term_plugs_in_and_moves_the_fit(body64) -> None:
    starts, evidence = reference_problem(body64)
    config = EvidenceConfig()
    plain = condition_on_keypoints(body64, starts, evidence, config)
    pull = ShapePull(index=3, target=2.0, sigma=0.05)
    pulled = condition_on_keypoints(body64, starts, evidence, config, extra_terms=[pull])
    assert plain.terms == ("keypoints",) and pulled.terms == ("keypoints", "shape_pull")
    before, after = plain.conditioned.shape_mean[3], pulled.conditioned.shape_mean[3]
    assert abs(before - 2.0) > 1.0 and abs(after - 2.0) < 0.05  # the term moved the fit
    # ... and the Laplace step counted its evidence: that coefficient is now about sigma sure
    assert pulled.conditioned.shape_std[3] < 0.06 < 0.5 < plain.conditioned.shape_std[3]
    others = [i for i in range(10) if i != 3]
    assert (pulled.conditioned.shape_std[others] > 0.3).all()
    assert pulled.keypoint_weights.shape == (17,)


def test_a_robust_term_reports_its_weights(body64) -> None:
    starts, evidence = reference_problem(body64)
    config = EvidenceConfig(max_iterations=10)
    far = ShapePull(index=0, target=40.0, sigma=0.05, robust_scale=1.0)
    result = fit_evidence(body64, starts, [KeypointTerm(evidence, config), far], config)
    assert set(result.robust_weights) == {"keypoints", "shape_pull"}
    assert result.robust_weights["shape_pull"].shape == (2, 1)
    # 800 sigmas off at the start, the Cauchy loss leaves the pull weak: no jump to 40
    assert (result.robust_weights["shape_pull"] < 0.01).all()
    assert (result.state.betas[:, 0] < 5.0).all()


def test_a_term_reading_vertices_sees_them_and_leaves_the_keypoints_as_they_were(body64):
    starts, evidence = reference_problem(body64)
    config = EvidenceConfig(max_iterations=2, facings=1)  # the probe sees the solver's calls only
    probe = VertexProbe()
    plain = condition_on_keypoints(body64, starts.rows(slice(0, 1)), evidence, config)
    probed = condition_on_keypoints(
        body64, starts.rows(slice(0, 1)), evidence, config, extra_terms=[probe]
    )
    assert (86, 1, body64.num_vertices, 3) in probe.shapes  # 85 perturbations + the state
    # Posed with its vertices, the body has the same keypoints; the probe's zero residual
    # changes only the summation order of the Hessian's products (float noise, through the
    # finite differences' 1e-6 step).
    pairs = zip(probed.conditioned.tensors(), plain.conditioned.tensors(), strict=True)
    for mine, theirs in pairs:
        torch.testing.assert_close(mine, theirs, rtol=1e-6, atol=1e-9)


def test_malformed_terms_are_refused_with_their_name(body64) -> None:
    starts, evidence = reference_problem(body64)
    config = EvidenceConfig()
    with pytest.raises(ValueError, match="unique names"):
        fit_evidence(body64, starts, [KeypointTerm(evidence, config)] * 2, config)
    wrong = ShapePull(index=0, target=0.0, sigma=1.0)
    wrong.residual_shape = (2, 1)
    with pytest.raises(ValueError, match="'shape_pull' returned residuals of shape"):
        fit_evidence(body64, starts, [KeypointTerm(evidence, config), wrong], config)


def test_marginalising_the_camera_is_the_schur_complement_of_a_known_gaussian() -> None:
    generator = torch.Generator().manual_seed(5)
    root = torch.randn(85, 85, generator=generator, dtype=torch.float64)
    precision = root @ root.T + 5.0 * torch.eye(85, dtype=torch.float64)
    kept = torch.cat((torch.arange(0, 69), torch.arange(75, 85)))
    conditional = pose_shape_precision(precision, "conditional")
    marginal = pose_shape_precision(precision, "marginal")
    torch.testing.assert_close(conditional, precision[kept][:, kept])
    # the marginal's covariance is the full covariance's pose-and-shape block
    covariance = torch.linalg.inv(precision)[kept][:, kept]
    torch.testing.assert_close(torch.linalg.inv(marginal), covariance, rtol=1e-9, atol=1e-12)
    # integrating unknowns out can only widen: every marginal std is at least the conditional
    conditional_std = torch.linalg.inv(conditional).diagonal().sqrt()
    marginal_std = covariance.diagonal().sqrt()
    assert (marginal_std >= conditional_std - 1e-12).all()
    assert (marginal_std > 1.01 * conditional_std).any()


def test_height_trades_off_against_the_camera_scale_only_when_it_is_marginalised(body64):
    starts, evidence = reference_problem(body64)
    fixed = condition_on_keypoints(body64, starts, evidence, REFERENCE_CONFIG)
    marginal = replace(REFERENCE_CONFIG, rigid_spread="marginal")
    free = condition_on_keypoints(body64, starts, evidence, marginal)
    # same fit, same modes: only the spreads differ
    torch.testing.assert_close(free.conditioned.shape_mean, fixed.conditioned.shape_mean)
    torch.testing.assert_close(free.conditioned.global_orient, fixed.conditioned.global_orient)
    # the camera scale explains what height (β₀) would: marginalised, β₀ is much less sure
    assert free.conditioned.shape_std[0] > 1.5 * fixed.conditioned.shape_std[0]
    assert (free.conditioned.shape_std >= fixed.conditioned.shape_std - 1e-9).all()
    assert not torch.allclose(free.conditioned.F, fixed.conditioned.F)
    # "shape": the shape Gaussian marginalised, the joints exactly as before
    shape_only = replace(REFERENCE_CONFIG, rigid_spread="shape")
    shape = condition_on_keypoints(body64, starts, evidence, shape_only)
    assert EvidenceConfig().rigid_spread == "conditional"
    assert torch.equal(shape.conditioned.F, fixed.conditioned.F)
    torch.testing.assert_close(shape.conditioned.shape_std, free.conditioned.shape_std)

"""The fit's evidence as a list of terms: the keypoint-only fit is unchanged against a reference
recorded before the terms existed, and a new term plugs in without touching the solver."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import roma
import torch

from hkpd.body import BodyModel
from hkpd.camera_conventions import FRONTAL_GLOBAL_ORIENT, ndc_to_pixels
from hkpd.conditioning import EvidenceConfig, KeypointEvidence, KeypointFit, condition_on_keypoints
from hkpd.distributions import BodyDistribution

SIZE = 160
REFERENCE = Path(__file__).parent / "data" / "keypoint_fit_reference.npz"
"""The fit of :func:`reference_problem` as the code computed it before the evidence became a
list of terms (written once by :func:`write_reference`)."""


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
    fit = condition_on_keypoints(body64, starts, evidence, EvidenceConfig())
    np.savez(REFERENCE, **_fit_record(fit))


def test_keypoint_only_fit_matches_the_reference(body64) -> None:
    starts, evidence = reference_problem(body64)
    fit = condition_on_keypoints(body64, starts, evidence, EvidenceConfig())
    reference = np.load(REFERENCE)
    record = _fit_record(fit)
    assert set(record) == set(reference.files)
    for name, value in record.items():
        np.testing.assert_allclose(value, reference[name], rtol=1e-9, atol=1e-12, err_msg=name)
    weights = record["keypoint_weights"]
    assert weights[7] < 0.5 < weights[:7].min() and weights[16] == 0.0  # outlier, hidden

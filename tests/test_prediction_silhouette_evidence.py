"""The predictor conditions on the person mask only when asked, and says which evidence it used."""

from __future__ import annotations

import pytest
import torch

from hkpd.explorer.demo_photo import shipped_photo
from hkpd.prediction import KeypointDetector, Predictor


@pytest.fixture(scope="module")
def predictor():
    predictor = Predictor.from_pretrained(device="cpu")
    yield predictor
    predictor.close()


def test_the_mask_is_evidence_only_when_asked(predictor) -> None:
    photo = shipped_photo()
    keypoints_only = predictor.predict(photo)
    assert keypoints_only.evidence_fit.terms == ("keypoints", "landmarks")
    predictor.silhouette_evidence = True
    try:
        with_mask = predictor.predict(photo)
    finally:
        predictor.silhouette_evidence = False
    assert with_mask.conditioned
    assert with_mask.network_input.person_mask is not None
    assert with_mask.evidence_fit.terms == ("keypoints", "silhouette", "landmarks")
    # the mask moves the fit (shape and pose), within the same families
    assert not torch.equal(with_mask.shape_mean, keypoints_only.shape_mean)
    assert with_mask.F.shape == keypoints_only.F.shape


def test_without_a_mask_the_fit_falls_back_to_the_keypoints(predictor) -> None:
    plain = Predictor(
        predictor.network,
        "cpu",
        body=predictor.body,
        detector=KeypointDetector(segmentation=False),
        silhouette_evidence=True,
    )
    try:
        posterior = plain.predict(shipped_photo())
    finally:
        plain.close()
    assert posterior.network_input.person_mask is None
    assert posterior.conditioned and posterior.evidence_fit.terms == ("keypoints", "landmarks")


def test_a_mask_fit_marginalises_the_camera_for_the_shape(predictor) -> None:
    from dataclasses import replace

    from hkpd.conditioning import EvidenceConfig

    assert EvidenceConfig().for_mask_evidence().rigid_spread == "shape"
    for explicit in ("shape", "marginal"):
        config = EvidenceConfig(rigid_spread=explicit)
        assert config.for_mask_evidence() is config
    photo = shipped_photo()
    predictor.silhouette_evidence = True
    try:
        automatic = predictor.predict(photo)
        saved = predictor.evidence_config
        predictor.evidence_config = replace(saved, rigid_spread="shape")
        try:
            explicit = predictor.predict(photo)
        finally:
            predictor.evidence_config = saved
    finally:
        predictor.silhouette_evidence = False
    # The predictor's mask fit is the "shape" Laplace step: the same posterior, bit for bit.
    assert torch.equal(automatic.shape_std, explicit.shape_std)
    assert torch.equal(automatic.F, explicit.F)
    # Keypoints alone keep the product's default (camera held fixed): β₀ is surer there.
    keypoints_only = predictor.predict(photo)
    assert keypoints_only.shape_std[0] < automatic.shape_std[0]

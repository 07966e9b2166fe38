"""BodyPosterior.turned_around(): the same keypoints fitted by a body facing the other way."""

from __future__ import annotations

import pytest
import torch

from hkpd.assets import shipped_file
from hkpd.coco_keypoints import COCO17_MIRROR_ORDER
from hkpd.conditioning import faces_camera
from hkpd.prediction import Predictor
from hkpd.prediction.turning import turned_distribution

PHOTO = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    torch.set_num_threads(1)
    return Predictor.from_pretrained(device="cpu")


def test_the_turned_twin_projects_to_the_same_points_and_is_its_own_inverse(predictor) -> None:
    posterior = predictor.predict(PHOTO, evidence=False)
    turned = turned_distribution(posterior.distribution)
    again = turned_distribution(turned)
    for mine, theirs in zip(again.tensors(), posterior.distribution.tensors(), strict=True):
        assert torch.allclose(mine, theirs)
    assert torch.allclose(torch.linalg.det(turned.global_orient), torch.tensor(1.0), atol=1e-5)
    from dataclasses import replace

    twin = replace(posterior, distribution=turned)
    order = list(COCO17_MIRROR_ORDER)
    original = posterior.mode().keypoints2d[0]
    assert torch.allclose(twin.mode().keypoints2d[0][order], original, atol=0.05)
    assert bool(faces_camera(posterior.global_orient)) != bool(faces_camera(turned.global_orient))


def test_turning_an_evidence_posterior_refits_and_turns_back(predictor) -> None:
    posterior = predictor.predict(PHOTO, sex="male")
    turned = posterior.turned_around()
    assert turned.turned and turned.conditioned and turned.sex_probabilities["male"] == 1.0
    assert bool(faces_camera(posterior.global_orient)) != bool(faces_camera(turned.global_orient))
    order = list(COCO17_MIRROR_ORDER)
    shown = posterior.evidence.bool()
    error = (turned.mode().keypoints2d[0][order] - posterior.keypoints).norm(dim=-1)[shown]
    assert float(error.median()) < 25  # photo pixels: the swapped labels are explained
    # its quality compares the turned body's left keypoints with the detector's right ones
    assert "keypoints_not_fitted" not in turned.quality.flags
    assert "turned_copy" in turned.quality.flags
    assert turned.quality.signals["misfit"] < 2 * posterior.quality.signals["misfit"] + 0.02
    assert turned.turned_around() is posterior
    with pytest.raises(ValueError, match="cannot be turned around"):
        predictor.predict(PHOTO, evidence=False).turned_around()


def test_turning_keeps_the_photos_sex_reading(predictor) -> None:
    posterior = predictor.predict(PHOTO)  # the face tells the sex
    turned = posterior.turned_around()
    assert turned.sex_probabilities == pytest.approx(posterior.sex_probabilities)
    assert turned.sex_evidence == posterior.sex_evidence
    assert turned.face == posterior.face
    assert turned.drawn_sex in ("male", "neutral")  # neutral only if the turn is in doubt

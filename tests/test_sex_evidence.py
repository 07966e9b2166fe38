"""The face as evidence of the sex beside the keypoints, and the body that claims no sex
(:mod:`hkpd.prediction.sex_latent`)."""

from __future__ import annotations

import math

import pytest
import torch

from hkpd.prediction.sex_latent import (
    NEUTRAL,
    SURE_SEX_PROBABILITY,
    SexEvidence,
    SexShapes,
    face_log_odds,
    sex_probabilities,
)


def _shapes(p_male: float, stated: bool = False) -> SexShapes:
    means = {"female": torch.full((10,), -1.0), "male": torch.full((10,), 3.0)}
    covariances = {sex: torch.eye(10) for sex in means}
    probabilities = {"female": 1.0 - p_male, "male": p_male}
    return SexShapes(probabilities, means, covariances, stated)


def test_the_face_adds_its_log_odds_to_the_keypoints() -> None:
    keypoints = {"female": -5.0, "male": -5.0 + math.log(0.41 / 0.59)}  # P(male) 0.41
    alone = sex_probabilities(keypoints)
    assert alone["male"] == pytest.approx(0.41)
    with_face = sex_probabilities(keypoints, 0.97)
    odds = (0.41 / 0.59) * (0.97 / 0.03)
    assert with_face["male"] == pytest.approx(odds / (1 + odds))
    assert with_face["female"] == pytest.approx(1 - with_face["male"])
    # A face that said nothing changes nothing.
    assert sex_probabilities(keypoints, None) == alone


def test_the_face_is_clipped_and_works_without_keypoint_evidence() -> None:
    assert face_log_odds(1.0) == pytest.approx(math.log(999))
    assert face_log_odds(0.0) == pytest.approx(-math.log(999))
    assert face_log_odds(float("nan")) == 0.0
    no_fits = sex_probabilities({"female": float("nan"), "male": float("nan")}, 0.9)
    assert no_fits["male"] == pytest.approx(0.9)


def test_an_unsure_sex_draws_the_shared_build() -> None:
    unsure = _shapes(0.6)
    assert not unsure.sure
    assert unsure.drawn == NEUTRAL
    assert torch.allclose(unsure.drawn_mean(), torch.full((10,), 1.0))
    sure = _shapes(SURE_SEX_PROBABILITY + 0.01)
    assert sure.sure and sure.drawn == "male"
    assert torch.equal(sure.drawn_mean(), sure.means["male"])


def test_a_doubted_reading_claims_no_sex_unless_stated() -> None:
    confident = _shapes(0.97)
    assert confident.with_doubt().drawn == NEUTRAL
    assert confident.with_doubt(False).drawn == "male"
    stated = _shapes(1.0, stated=True).with_doubt()
    assert stated.sure and stated.drawn == "male"


def test_scaling_keeps_the_evidence_and_the_doubt() -> None:
    evidence = SexEvidence(keypoints=0.41, face=0.97)
    shapes = SexShapes(
        {"female": 0.1, "male": 0.9},
        {"female": torch.zeros(10), "male": torch.ones(10)},
        {"female": torch.eye(10), "male": torch.eye(10)},
        evidence=evidence,
        doubted=True,
    )
    scaled = shapes.scaled(2.0)
    assert scaled.evidence == evidence and scaled.doubted
    assert torch.allclose(scaled.covariances["male"], 4 * torch.eye(10))
    assert evidence.as_dict() == {"face": 0.97, "keypoints": 0.41}
    assert evidence.source == "face"
    assert SexEvidence(keypoints=0.5, face_reason="no face").source == "keypoints"


def test_a_warning_doubts_a_face_read_sex_only_when_the_person_may_be_someone_else() -> None:
    from hkpd.prediction.quality import ReadingQuality
    from hkpd.prediction.sex_fits import doubts_the_sex

    faced = SexShapes(
        {"female": 0.02, "male": 0.98},
        {"female": torch.zeros(10), "male": torch.ones(10)},
        {"female": torch.eye(10), "male": torch.eye(10)},
        evidence=SexEvidence(keypoints=0.6, face=0.99),
    )
    keypoints_only = SexShapes(
        faced.probabilities, faced.means, faced.covariances, evidence=SexEvidence(keypoints=0.98)
    )
    fine = ReadingQuality(0.9, (), {})
    cut_off = ReadingQuality(0.3, ("cut_off_by_edge", "readers_disagree"), {})
    neighbour = ReadingQuality(0.3, ("off_centre_in_box",), {})
    assert not doubts_the_sex(faced, fine) and not doubts_the_sex(keypoints_only, fine)
    assert not doubts_the_sex(faced, cut_off)
    assert doubts_the_sex(keypoints_only, cut_off)
    assert doubts_the_sex(faced, neighbour)


def test_the_body_section_says_why_the_face_did_not_settle_the_sex() -> None:
    from types import SimpleNamespace

    from hkpd.explorer.body_text import face_clause

    def posterior(evidence: SexEvidence | None, doubted: bool = False) -> SimpleNamespace:
        return SimpleNamespace(sexes=SimpleNamespace(evidence=evidence, doubted=doubted))

    off = posterior(SexEvidence(keypoints=0.5))
    assert face_clause(off) == "the face was not read (switched off)"
    back = posterior(SexEvidence(keypoints=0.5, face_reason="the head is turned away"))
    assert face_clause(back) == "the face said nothing: the head is turned away"
    weak = posterior(SexEvidence(keypoints=0.5, face=0.25))
    assert face_clause(weak) == "the face's word (female 75 %) is not clear enough"
    assert "in doubt" in face_clause(posterior(SexEvidence(keypoints=0.9, face=0.99), True))

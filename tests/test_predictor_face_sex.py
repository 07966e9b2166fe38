"""The face as evidence of the sex through the whole predictor, on the shipped model and photo
(issue 57): the shipped photo's man is drawn as a man, occluders away from the face and the
person-mask switch do not flip a face-read sex, and without the face the body claims no sex."""

from __future__ import annotations

import pytest
import torch

from hkpd import Predictor
from hkpd.assets import shipped_file
from hkpd.prediction.exports.body_summary import body_summary, sex_statement

RIGHT_FOREARM = (377, 255, 473, 290)
RIGHT_SHIN = (470, 420, 540, 560)


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    torch.set_num_threads(1)
    return Predictor.from_pretrained(device="cpu")


@pytest.fixture(scope="module")
def photo() -> str:
    return str(shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "reinstall"))


@pytest.fixture(scope="module")
def read(predictor, photo):
    return predictor.predict(photo)


def test_the_shipped_man_is_read_male_from_his_face(read) -> None:
    assert read.sex_probabilities["male"] >= 0.9
    assert read.sex_evidence["face"] >= 0.9
    assert 0.0 < read.sex_evidence["keypoints"] < 1.0  # the proportions' own word, kept apart
    assert read.drawn_sex == "male"
    assert read.face is not None and not read.face.child
    assert sex_statement(read.sexes).endswith("from the face")
    summary = body_summary(read, {})
    assert summary["sex_evidence"] == read.sex_evidence
    assert summary["drawn_sex"] == "male"


def test_without_the_face_the_body_claims_no_sex(predictor, photo, read) -> None:
    alone = predictor.predict(photo, read_face=False)
    assert alone.sex_evidence["face"] is None
    assert alone.sex_evidence["keypoints"] == pytest.approx(read.sex_evidence["keypoints"])
    if max(alone.sex_probabilities.values()) < 0.8:
        assert alone.drawn_sex == "neutral"
        both = alone.sexes.means
        assert torch.allclose(alone.shape_mean, 0.5 * (both["female"] + both["male"]), atol=1e-5)
        assert sex_statement(alone.sexes).startswith("not sure")


@pytest.mark.parametrize("box", [RIGHT_FOREARM, RIGHT_SHIN])
def test_a_box_away_from_the_face_keeps_the_face_read_sex(predictor, photo, read, box) -> None:
    boxed = predictor.predict(photo, occluders=[box])
    assert boxed.drawn_sex == "male"
    assert abs(boxed.sex_probabilities["male"] - read.sex_probabilities["male"]) < 0.05


def test_the_mask_switch_keeps_the_face_read_sex(predictor, photo, read) -> None:
    predictor.silhouette_evidence = True
    try:
        masked = predictor.predict(photo)
    finally:
        predictor.silhouette_evidence = False
    assert masked.drawn_sex == "male" and masked.sex_probabilities["male"] >= 0.9


def test_a_stated_sex_overrides_the_face(predictor, photo) -> None:
    stated = predictor.predict(photo, sex="female")
    assert stated.sex_probabilities == {"female": 1.0, "male": 0.0}
    assert stated.drawn_sex == "female" and stated.sex_evidence is None

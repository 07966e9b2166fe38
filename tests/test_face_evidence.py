"""The face reading as the sex latent's word (:mod:`hkpd.prediction.face_evidence`)."""

from __future__ import annotations

from hkpd.prediction.detection.face_sex import FaceReading
from hkpd.prediction.face_evidence import CHILD_WORDS, face_word
from hkpd.prediction.sex_latent import FaceWord


def _reading(p_male: float | None, reason: str | None, age: float | None = 30.0) -> FaceReading:
    return FaceReading(p_male, 0.7, 0.8, age, 80.0, 0.95, 0.9, reason)


def test_a_read_face_speaks_and_a_gated_one_says_why() -> None:
    assert face_word(None) == FaceWord()
    spoken = face_word(_reading(0.93, None))
    assert spoken.p_male == 0.93 and spoken.reason is None and not spoken.child
    back = face_word(_reading(None, "back_view"))
    assert back.p_male is None and back.reason == "the head is turned away from the camera"


def test_a_childs_face_gives_no_word_and_a_note() -> None:
    child = face_word(_reading(None, "child", age=9.0))
    assert child.p_male is None and child.child and child.reason == CHILD_WORDS
    assert child.age_years == 9.0

"""The face's word on the sex, from the photo's face reading.

The face is read once per photo and person (:class:`~hkpd.prediction.detection.face_sex.
FaceSexReader`, kept in the photo's :class:`~hkpd.prediction.photo_reading.PhotoReading`): like
the rest of how a photo is read, it belongs to the photo, so an occluder edit neither reads it
again nor changes what it says (an occluder removes keypoint evidence from the fit). A face that
looks like a child's (the reader's ``"child"`` gate, faceres's age under
:data:`~hkpd.prediction.detection.face_sex.CHILD_AGE_YEARS`) gives no word on the sex (the
calibration was made on adults), and the reading gets a note: the body model is adult-only
(:attr:`FaceWord.child`, the quality flag ``looks_like_a_child``).
"""

from __future__ import annotations

from hkpd.prediction.detection.face_sex import FACE_GATE_REASONS, FaceReading
from hkpd.prediction.sex_latent import FaceWord

CHILD_WORDS = "the face looks like a child's"
"""The reason given for a child's face, in words."""


def face_word(reading: FaceReading | None) -> FaceWord:
    """What the face says: its calibrated P(male), or None with the reason in words (e.g.
    "the head is turned away from the camera") when it was gated out (a child's face:
    ``child`` set); an empty :class:`FaceWord` when the face was not read (``reading`` None)."""
    if reading is None:
        return FaceWord()
    age = reading.age_years
    if reading.reason == "child":
        return FaceWord(None, CHILD_WORDS, age_years=age, child=True)
    if reading.p_male is None:
        reason = FACE_GATE_REASONS.get(reading.reason or "", reading.reason)
        return FaceWord(None, reason or "no face was read", age_years=age)
    return FaceWord(float(reading.p_male), None, age_years=age)

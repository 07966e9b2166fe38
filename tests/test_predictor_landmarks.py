"""The predictor weighs the hand and foot landmarks the photo shows, not those under a box, and
they narrow the shown feet and hands (the shipped model and photo)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.assets import shipped_file
from hkpd.body.extremity_landmarks import BLAZEPOSE_EXTREMITY_NAMES
from hkpd.prediction import Predictor

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def predictor():
    torch.set_num_threads(1)
    predictor = Predictor.from_pretrained(device="cpu")
    yield predictor
    predictor.close()


def part_spread(posterior, part: str) -> float:
    spread = posterior.vertex_uncertainty(100, seed=0)
    body = posterior.body
    return float(spread[body.part_labels == body.part_names.index(part)].mean())


def test_landmarks_are_evidence_and_narrow_the_shown_foot(predictor: Predictor) -> None:
    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")
    predictor.landmark_evidence = False
    try:
        without = predictor.predict(photo)
    finally:
        predictor.landmark_evidence = True
    with_landmarks = predictor.predict(photo)
    assert "landmarks" not in without.evidence_fit.terms
    assert with_landmarks.evidence_fit.terms[-1] == "landmarks"
    assert with_landmarks.network_input.extremity_evidence.all()  # every one shown
    for part in ("left_ankle", "left_foot"):
        assert part_spread(with_landmarks, part) < 0.9 * part_spread(without, part)
    feet = with_landmarks.mode().foot_keypoints2d[0].numpy()
    heels = with_landmarks.network_input.detection.extremities[6:8]
    # the fitted heels lie near the detected ones (within 5 % of the person box's height)
    box = with_landmarks.network_input.detection.person_box
    assert np.linalg.norm(feet[[2, 5]] - heels, axis=1).max() < 0.05 * (box[3] - box[1])


def test_a_box_over_a_foot_hides_its_landmarks(predictor: Predictor) -> None:
    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")
    clear = predictor.predict(photo)
    detection = clear.network_input.detection
    rows = [BLAZEPOSE_EXTREMITY_NAMES.index(n) for n in ("right_heel", "right_foot_index")]
    points = np.vstack([detection.extremities[rows], detection.keypoints[16:17]])  # + ankle
    box = np.r_[points.min(0) - 15, points.max(0) + 15]
    covered = predictor.predict(photo, occluders=[box])
    shown = covered.network_input.extremity_evidence
    assert not shown[rows].any() and shown[[i for i in range(10) if i not in rows]].all()
    assert not covered.network_input.evidence[16]
    parts = ("right_ankle", "right_foot")  # the foot and the toes
    spread = {name: sum(part_spread(posterior, p) for p in parts) for name, posterior in
              (("clear", clear), ("covered", covered))}  # fmt: skip
    # 1.48 while the fit tempered every joint's prior; since issue 58 item 3 a joint the evidence
    # does not read keeps the network's full weight (1.32 on this photo), so the covered foot is
    # no wider than the network alone says it is.
    assert spread["covered"] / spread["clear"] > 1.25
    network = predictor.predict(photo, occluders=[box], evidence=False)
    assert spread["covered"] <= 1.1 * sum(part_spread(network, p) for p in parts)

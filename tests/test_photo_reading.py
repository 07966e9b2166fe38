"""A box removes evidence and does not change how the photo is read (issue 58 items 2, 3, 10):
the shipped predictor on the shipped photo, with the photo reading kept while occluders change."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hkpd.assets import shipped_file
from hkpd.prediction import Predictor
from hkpd.prediction.photo_reading import PhotoReadingCache

PHOTO = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "")
SHIN = (385.2, 363.7, 465.0, 583.8)
"""A box over the person's right knee and ankle (``benchmarks/bench_explorer.shin_box``)."""
FOREARM = (377.0, 255.0, 473.0, 290.0)
"""A box over the right forearm (issue 58's ``--occluder 377 255 473 290``)."""
RIGHT_LEG = {"right_hip", "right_knee", "right_ankle", "right_foot"}
"""The parts that box hides or that hang below it (thigh, shin, foot, toes)."""


@pytest.fixture(scope="module")
def predictor() -> Predictor:
    torch.set_num_threads(1)
    return Predictor.from_pretrained(device="cpu")


@pytest.fixture(scope="module")
def clear(predictor: Predictor):
    return predictor.predict(PHOTO)


def test_a_box_over_one_shin_moves_that_leg_only(predictor: Predictor, clear) -> None:
    boxed = predictor.predict(PHOTO, occluders=[SHIN])
    assert boxed.mirror_read == clear.mirror_read
    assert boxed.upright_tilt_degrees == clear.upright_tilt_degrees
    assert abs(boxed.sex_probability - clear.sex_probability) <= 0.05
    before, after = clear.part_uncertainty(), boxed.part_uncertainty()
    ratios = {part: after[part] / before[part] for part in before if part not in RIGHT_LEG}
    assert max(abs(ratio - 1.0) for ratio in ratios.values()) <= 0.15, ratios
    assert after["right_knee"] > 1.5 * before["right_knee"]  # the hidden shin does move


def test_evidence_does_not_widen_a_hidden_forearm(predictor: Predictor) -> None:
    evidence = predictor.predict(PHOTO, occluders=[FOREARM]).part_uncertainty()
    network = predictor.predict(PHOTO, occluders=[FOREARM], evidence=False).part_uncertainty()
    for part in ("right_wrist", "right_hand"):
        assert evidence[part] <= 1.1 * network[part], (part, evidence[part], network[part])


def test_an_occluder_edit_reuses_the_photo_reading(predictor: Predictor, clear) -> None:
    detections, batches = [], []
    detect, network = predictor.detector.detect, predictor.reading.network.network
    predictor.detector.detect = lambda *a, **k: detections.append(1) or detect(*a, **k)
    hook = network.register_forward_hook(lambda _m, inputs, _o: batches.append(len(inputs[0])))
    try:
        boxed = predictor.predict(PHOTO, occluders=[(SHIN[0] - 3, SHIN[1], SHIN[2], SHIN[3])])
    finally:
        hook.remove()
        del predictor.detector.detect
    assert detections == []  # the photo's detection is kept
    assert batches == [1]  # one reading, read once, mirrored as the photo chose
    assert boxed.network_input.detection is clear.network_input.detection
    assert boxed.sex_probabilities == clear.sex_probabilities


def test_without_occluders_the_kept_reading_gives_the_same_posterior(
    predictor: Predictor, clear
) -> None:
    again = predictor.predict(PHOTO)
    explicit = predictor.predict(PHOTO, reading=predictor.read_photo(PHOTO))
    for posterior in (again, explicit):
        pairs = zip(posterior.distribution.tensors(), clear.distribution.tensors(), strict=True)
        assert all(torch.equal(mine, theirs) for mine, theirs in pairs)
        assert posterior.sex_probabilities == clear.sex_probabilities


def test_a_first_boxed_prediction_weighs_the_sexes_on_the_clear_photo(clear) -> None:
    fresh = Predictor.from_pretrained(device="cpu")  # knows nothing of this photo yet
    boxed = fresh.predict(PHOTO, occluders=[SHIN])
    assert boxed.sex_probabilities == pytest.approx(clear.sex_probabilities, abs=1e-9)


def test_the_cache_keeps_the_last_readings_and_tells_photos_apart(predictor: Predictor) -> None:
    pixels = np.asarray(predictor.read_photo(PHOTO).image.pixels)
    first, second = predictor.read_photo(pixels), predictor.read_photo(pixels.copy())
    assert first is second  # same pixels, same reading
    changed = pixels.copy()
    changed[:40, :40] = 0  # a corner far from the person: another photo all the same
    assert predictor.read_photo(changed) is not first
    cache = PhotoReadingCache(size=2)
    readings = [type("R", (), {"key": key})() for key in "abc"]
    for reading in readings:
        cache.put(reading)  # type: ignore[arg-type]
    assert cache.get("a") is None and cache.get("c") is readings[2]

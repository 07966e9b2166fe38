"""The predictor with the second keypoint reader (issue 59): on by default, read once per photo
and box, off with ``second_reader=False``."""

from __future__ import annotations

import numpy as np
import torch

from hkpd.assets import shipped_file


def test_the_predictor_reads_the_photo_once_with_both_readers_and_can_be_told_not_to() -> None:
    """Default on: the quality score reads the two readers' agreement; an occluder edit of the
    same photo re-uses the second reading (the reader runs once); ``second_reader=False``
    reads BlazePose alone (the reader signals are not measured)."""
    from hkpd.prediction import Predictor

    torch.set_num_threads(1)
    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "reinstall")
    predictor = Predictor.from_pretrained(device="cpu")
    calls = []
    reader = predictor.second_reader
    original = reader.read

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    reader.read = counted
    posterior = predictor.predict(photo)
    signals = posterior.quality.signals
    assert np.isfinite(signals["log10_readers_distance"]) and signals["log10_readers_distance"] < -1
    assert "readers_disagree" not in posterior.quality.flags
    assert posterior.network_input.detection.second_reading is not None
    box = posterior.network_input.detection.person_box
    shin = (box[0], (box[1] + box[3]) / 2, (box[0] + box[2]) / 2, box[3])
    boxed = predictor.predict(photo, occluders=[shin])
    assert len(calls) == 1
    assert boxed.quality.signals["readers_swap_gain"] == signals["readers_swap_gain"]
    alone = predictor.predict(photo, second_reader=False)
    assert len(calls) == 1 and alone.network_input.detection.second_reading is None
    assert np.isnan(alone.quality.signals["readers_disputed_share"])
    predictor.close()


def test_a_wrist_the_readers_dispute_is_left_to_the_network_and_widens() -> None:
    """A second reading that agrees everywhere but puts the left wrist elsewhere (0.4 of the
    person's size): the wrist (and BlazePose's left hand landmarks) leave the fit's evidence, so
    the left forearm and hand are more uncertain than when the readers agree (1.5-1.6x when
    written), and the right hand barely moves."""
    from hkpd.prediction import Predictor
    from hkpd.prediction.detection.movenet import SecondReading
    from hkpd.prediction.detection.warp import Region
    from hkpd.prediction.reader_agreement import person_size

    torch.set_num_threads(1)
    photo = shipped_file(("photos", "warrior_lunge.jpg"), "the shipped photo", "reinstall")
    predictor = Predictor.from_pretrained(device="cpu")
    moved = {"wrist": 0.0}

    def fake_read(image, detection, bbox=None):
        points = np.asarray(detection.keypoints, np.float64) + 2.0
        points[9, 0] += moved["wrist"] * person_size(detection.person_box)
        return SecondReading(points, np.full(17, 0.9), Region(np.zeros(2), 1.0, 0.0), 0.0)

    predictor.second_reader.read = fake_read
    agreeing = predictor.predict(photo)
    assert agreeing.evidence_fit is not None
    predictor._photo_readings.clear()
    moved["wrist"] = 0.4
    disputed = predictor.predict(photo)
    assert (
        disputed.network_input.detection.second_reading.keypoints[9, 0]
        > (agreeing.network_input.detection.second_reading.keypoints[9, 0])
    )
    before, after = agreeing.part_uncertainty(100), disputed.part_uncertainty(100)
    assert after["left_hand"] > 1.3 * before["left_hand"], (before, after)  # 1.6x measured
    assert after["left_wrist"] > 1.3 * before["left_wrist"]
    assert abs(after["right_hand"] - before["right_hand"]) < 0.2 * before["right_hand"]
    predictor.close()

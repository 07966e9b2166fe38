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

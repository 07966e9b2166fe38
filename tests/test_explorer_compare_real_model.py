"""Compare's ``network`` B is the network reading A's keypoint fit updated
(:func:`hkpd.explorer.compare.network_reading`): with the shipped model on the shipped photo it
is bit-identical to predicting with the evidence off, with and without a box."""

from __future__ import annotations

import pytest
import torch

from hkpd.explorer.compare import network_reading
from hkpd.explorer.demo_photo import shipped_photo
from hkpd.prediction import Predictor, load_image


@pytest.mark.slow
@pytest.mark.parametrize("boxes", [None, [(377.0, 255.0, 473.0, 290.0)]])
def test_the_fit_s_network_reading_is_the_network_only_prediction(boxes) -> None:
    try:
        predictor = Predictor.from_pretrained(device="cpu")
    except FileNotFoundError as error:
        pytest.skip(f"no shipped model: {error}")
    photo = load_image(shipped_photo()).pixels
    reading = network_reading(predictor.predict(photo, occluders=boxes))
    alone = predictor.predict(photo, occluders=boxes, evidence=False)
    assert reading is not None and reading.source == "network" == alone.source
    for mine, theirs in zip(
        reading.distribution.tensors(), alone.distribution.tensors(), strict=True
    ):
        assert torch.equal(mine, theirs)
    assert torch.equal(reading.keypoints, alone.keypoints)

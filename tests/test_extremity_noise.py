"""Detector-like noise on the hand and foot landmarks: the groups' own jitter, swaps within
left/right pairs, hidden landmarks never reported; the keypoints' draws unchanged."""

from __future__ import annotations

import pytest
import torch

from hkpd.coco_keypoints import COCO17_LEFT_RIGHT_PAIRS
from hkpd.synthesis.detector_noise import (
    EXTREMITY_LEFT_RIGHT_PAIRS,
    FOOT_NOISE,
    HAND_NOISE,
    DetectorNoise,
    detector_like_extremities,
    detector_like_keypoints,
)

SIZE = 256


def test_pairs_are_left_right_of_each_landmark() -> None:
    assert EXTREMITY_LEFT_RIGHT_PAIRS == ((0, 1), (2, 3), (4, 5), (6, 7), (8, 9))


def test_each_group_gets_its_own_jitter_and_hidden_ones_stay_hidden() -> None:
    count = 4000
    exact = torch.rand(count, 10, 2, generator=torch.Generator().manual_seed(0)) * SIZE
    visible = torch.ones(count, 10, dtype=torch.bool)
    visible[:, 3] = False
    quiet = {"outlier_rate": 0.0, "swap_rate": 0.0, "miss_rate": 0.0}
    hand = DetectorNoise(sigma=0.03, **quiet)
    foot = DetectorNoise(sigma=0.01, **quiet)
    detected, reported = detector_like_extremities(
        exact, visible, SIZE, torch.Generator().manual_seed(1), hand, foot
    )
    errors = (detected - exact) / SIZE
    assert errors[:, :6].std().item() == pytest.approx(0.03, rel=0.05)
    assert errors[:, 6:].std().item() == pytest.approx(0.01, rel=0.05)
    assert not reported[:, 3].any() and reported[:, [0, 1, 2, 4, 5, 6, 7, 8, 9]].all()
    assert HAND_NOISE.sigma > FOOT_NOISE.sigma > DetectorNoise().sigma


def test_swaps_exchange_left_and_right_only() -> None:
    exact = torch.arange(10, dtype=torch.float64)[None, :, None].expand(1, 10, 2).clone()
    always = DetectorNoise(sigma=0.0, outlier_rate=0.0, swap_rate=1.0, miss_rate=0.0)
    detected, _ = detector_like_extremities(
        exact, torch.ones(1, 10, dtype=torch.bool), SIZE, torch.Generator(), always, always
    )
    assert detected[0, :, 0].tolist() == [1, 0, 3, 2, 5, 4, 7, 6, 9, 8]
    with pytest.raises(ValueError, match=r"\(B, 10, 2\)"):
        detector_like_extremities(exact[:, :6], torch.ones(1, 6, dtype=torch.bool), SIZE,
                                  torch.Generator())  # fmt: skip


def test_keypoint_draws_are_unchanged_by_the_pairs_argument() -> None:
    exact = torch.rand(8, 17, 2, generator=torch.Generator().manual_seed(2)) * SIZE
    visible = torch.ones(8, 17, dtype=torch.bool)
    first = detector_like_keypoints(
        exact, visible, SIZE, DetectorNoise(), torch.Generator().manual_seed(3)
    )
    second = detector_like_keypoints(
        exact, visible, SIZE, DetectorNoise(), torch.Generator().manual_seed(3),
        COCO17_LEFT_RIGHT_PAIRS,
    )  # fmt: skip
    assert torch.equal(first[0], second[0]) and torch.equal(first[1], second[1])

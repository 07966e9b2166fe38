"""prepare_network_input: occluders before detection, hidden keypoints dropped, proxy layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hkpd.prediction import (
    KeypointDetection,
    KeypointDetector,
    LoadedImage,
    apply_occluders,
    points_under_boxes,
    prepare_network_input,
)
from hkpd.prediction.readings.upright_view import UprightView

DEMO_PHOTO = Path("/work/shared/data/demo_photos/yogait_t5.jpg")


class FixedDetector:
    """Returns fixed keypoints and records the pixels it was shown."""

    def __init__(self, keypoints: np.ndarray) -> None:
        self.keypoints = keypoints
        self.seen: list[np.ndarray] = []

    def detect(self, image: LoadedImage, bbox: object = None) -> KeypointDetection:
        self.seen.append(image.pixels.copy())
        return KeypointDetection(
            keypoints=self.keypoints,
            confidences=np.full(17, 0.95),
            person_box=np.array([0.0, 0.0, 1.0, 1.0]),
            mask_box=None,
            search_box=None,
            image_size=image.original_size,
            seconds=0.0,
        )


def test_points_under_boxes_agrees_with_the_painted_pixels() -> None:
    rng = np.random.default_rng(0)
    image = np.full((50, 70), 255, np.uint8)
    corner = rng.uniform(0, 45, (4, 2))
    boxes = np.concatenate([corner, corner + rng.uniform(2.5, 20, (4, 2))], 1)
    painted = apply_occluders(image, boxes)
    points = rng.uniform(-0.49, 49.49, (500, 2))
    pixel = np.floor(points + 0.5).astype(int)
    expected = painted[pixel[:, 1], pixel[:, 0]] == 0
    np.testing.assert_array_equal(points_under_boxes(points, boxes), expected)
    assert (
        points_under_boxes(points, []).shape == (500,) and not points_under_boxes(points, []).any()
    )


def test_the_detector_sees_the_unpainted_photo_and_occluded_keypoints_are_not_evidence() -> None:
    rng = np.random.default_rng(1)
    photo = rng.integers(60, 200, (480, 640, 3), dtype=np.uint8)
    keypoints = np.stack([np.linspace(250, 390, 17), np.linspace(60, 420, 17)], 1)
    occluder = (200, 300, 450, 480)  # covers the keypoints with v >= 300
    detector = FixedDetector(keypoints)
    prepared = prepare_network_input(photo, detector, occluders=[occluder])  # type: ignore[arg-type]

    # The detector saw the photo as it is (an occluder means "no evidence here", and BlazePose
    # on a painted photo put confident keypoints just outside the box); the edges see the box.
    np.testing.assert_array_equal(detector.seen[0], photo)
    assert not prepared.image.pixels[300:, 200:450].any()
    hidden = keypoints[:, 1] >= 299.5
    np.testing.assert_array_equal(prepared.confidences == 0, hidden)
    np.testing.assert_array_equal(prepared.evidence, ~hidden)  # carried, not read back
    np.testing.assert_array_equal(prepared.occluders.boxes, [occluder])
    np.testing.assert_array_equal(prepared.detection.confidences, 0.95)  # raw result untouched

    assert tuple(prepared.proxy.shape) == (18, 256, 256)
    heatmaps = prepared.proxy[1:].numpy()
    assert (heatmaps[hidden] == 0).all()
    for joint in np.flatnonzero(~hidden):
        v, u = np.unravel_index(heatmaps[joint].argmax(), heatmaps[joint].shape)
        np.testing.assert_allclose([u, v], prepared.keypoints_crop[joint], atol=0.5)
    np.testing.assert_allclose(
        prepared.crop.crop_to_image(prepared.keypoints_crop), keypoints, atol=1e-9
    )
    # The crop box surrounds all keypoints, the hidden ones included (the training rule).
    inside = prepared.keypoints_crop
    assert ((inside > 0) & (inside < 255)).all()
    edges = prepared.proxy[0].numpy()
    assert set(np.unique(edges)) <= {0.0, 1.0} and edges.any()

    small = prepare_network_input(photo, detector, crop_size=128)  # type: ignore[arg-type]
    assert tuple(small.proxy.shape) == (18, 128, 128) and small.crop_rgb.shape == (128, 128, 3)
    np.testing.assert_allclose(small.keypoints_crop, (prepared.keypoints_crop + 0.5) / 2 - 0.5)


def test_a_second_view_framed_on_the_box_keypoints_is_the_crop_whatever_is_covered() -> None:
    rng = np.random.default_rng(2)
    photo = rng.integers(60, 200, (480, 640, 3), dtype=np.uint8)
    keypoints = np.stack([np.linspace(250, 390, 17), np.linspace(60, 520, 17)], 1)  # feet cut
    detector = FixedDetector(keypoints)
    plain = prepare_network_input(photo, detector)  # type: ignore[arg-type]
    covered = prepare_network_input(photo, detector, occluders=[(200, 300, 450, 480)])  # type: ignore[arg-type]
    assert (covered.confidences == 0).sum() > 3  # the occluder hides evidence...
    # ...but not the points that frame a second view of the crop (the upright copy).
    np.testing.assert_array_equal(covered.box_keypoints_crop, plain.box_keypoints_crop)
    # Points below the photo are moved onto its border first, as for the crop itself.
    np.testing.assert_allclose(
        plain.crop.crop_to_image(plain.box_keypoints_crop)[:, 1].max(), 479.5, atol=1e-9
    )
    # Untilted, the view framed on them is the crop itself: same centre and side.
    size = plain.crop.size
    view = UprightView.from_tilt(0.0, covered.box_keypoints_crop, size)
    assert view.box.centre == pytest.approx(((size - 1) / 2, (size - 1) / 2), abs=1e-9)
    assert view.box.side == pytest.approx(size, abs=1e-9)
    # Framed on the evidence alone (unclipped), it would be another crop than the network's.
    evidence_only = UprightView.from_tilt(
        0.0, covered.keypoints_crop, size, covered.confidences > 0
    )
    assert abs(evidence_only.box.side / size - 1) > 0.05


@pytest.mark.skipif(not DEMO_PHOTO.is_file(), reason="demo photos not available")
def test_real_photo_with_the_legs_hidden() -> None:
    with KeypointDetector() as detector:
        prepared = prepare_network_input(DEMO_PHOTO, detector, occluders=[(400, 380, 760, 720)])
    legs = slice(13, 17)  # knees and ankles
    assert (prepared.confidences[legs] == 0).all()
    assert (prepared.confidences[:11] > 0.9).all()
    assert (prepared.proxy[1:][legs] == 0).all()
    assert prepared.image.original_size == (1080, 720)


def test_silhouette_and_rgb_proxies_from_a_photo() -> None:
    """The proxy ablation's networks read the person mask (occluders removed) or the colours."""
    rng = np.random.default_rng(2)
    photo = rng.integers(60, 200, (480, 640, 3), dtype=np.uint8)
    keypoints = np.stack([np.linspace(250, 390, 17), np.linspace(60, 420, 17)], 1)
    mask = np.zeros((480, 640), bool)
    mask[40:440, 230:410] = True
    detector = FixedDetector(keypoints)
    with pytest.raises(ValueError, match="reads a person silhouette: pass silhouette="):
        prepare_network_input(photo, detector, image_proxy="silhouette")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"must be \(480, 640\) like the photo"):
        prepare_network_input(photo, detector, image_proxy="silhouette", silhouette=mask[:100])  # type: ignore[arg-type]

    occluder = (200, 300, 450, 480)
    prepared = prepare_network_input(
        photo, detector, occluders=[occluder], image_proxy="silhouette", silhouette=mask
    )  # type: ignore[arg-type]
    crop_mask = prepared.crop_silhouette
    assert crop_mask is not None and crop_mask.dtype == bool and crop_mask.any()
    np.testing.assert_array_equal(prepared.proxy[0].numpy() == 1.0, crop_mask)
    # Nothing of the person is left under the occluder (rows >= 300 of the photo).
    covered = prepared.crop.image_to_crop(np.array([[320.0, 310.0]]))[0].round().astype(int)
    assert not crop_mask[covered[1]:, :].any()  # fmt: skip
    above = prepared.crop.image_to_crop(np.array([[320.0, 200.0]]))[0].round().astype(int)
    assert crop_mask[above[1], above[0]]

    rgb = prepare_network_input(photo, detector, image_proxy="rgb")  # type: ignore[arg-type]
    assert tuple(rgb.proxy.shape) == (20, 256, 256) and rgb.crop_silhouette is None
    np.testing.assert_allclose(
        rgb.proxy[:3].permute(1, 2, 0).numpy() * 255, rgb.crop_rgb, atol=1e-3
    )

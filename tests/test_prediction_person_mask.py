"""BlazePose's person mask: exact maps into the photo and the network's crop, occluders and the
photo's edge as "unknown", and a detector without segmentation changing nothing else."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch

from hkpd.prediction import KeypointDetection, KeypointDetector, LoadedImage, prepare_network_input
from hkpd.prediction.crop import CropTransform
from hkpd.prediction.detection.blazepose import PersonCandidate, PoseLandmarks
from hkpd.prediction.detection.boxes import search_region, validated_box
from hkpd.prediction.detection.person_mask import PersonMask
from hkpd.prediction.detection.warp import Region, crop_matrix
from hkpd.prediction.image_input import load_image
from hkpd.prediction.occluders import points_under_boxes

SHIPPED_PHOTO = Path(__file__).parents[1] / "assets" / "photos" / "warrior_lunge.jpg"
MASK_SIZE = 256


def ramp(points: np.ndarray) -> np.ndarray:
    """A linear function of original-photo pixels with values in (0, 1) on an 800 × 600 photo:
    bilinear resampling reproduces it exactly, so any error in the maps shows."""
    return 0.2 + 0.0004 * points[..., 0] + 0.0006 * points[..., 1]


class RampRunner:
    """A pose runner whose person stands in a rotated region and whose mask is :func:`ramp` of
    the original photo position each mask pixel shows (through the landmark crop's map)."""

    def __init__(self, loaded: LoadedImage, offset: tuple[int, int]) -> None:
        self.loaded, self.offset = loaded, np.asarray(offset, np.float64)
        self.region = Region(np.array([150.0, 130.0]), 180.0, 0.6)

    def find_people(self, pixels: np.ndarray) -> list[PersonCandidate]:
        box = np.array([100.0, 60.0, 200.0, 200.0])
        return [PersonCandidate(0.9, box, np.zeros((4, 2)), self.region)]

    def landmarks(
        self, pixels: np.ndarray, region: Region, segmentation: bool = False
    ) -> PoseLandmarks:
        rng = np.random.default_rng(0)
        points = region.to_photo(rng.uniform(0.3, 0.7, (33, 2)))
        to_photo = crop_matrix(region, MASK_SIZE)
        rows, cols = np.mgrid[0:MASK_SIZE, 0:MASK_SIZE]
        centres = np.stack([cols, rows], -1) @ to_photo[:, :2].T + to_photo[:, 2]
        original = self.loaded.to_original(centres + self.offset)
        mask = PersonMask(ramp(original).astype(np.float32), to_photo, pixels.shape[1::-1])
        return PoseLandmarks(points, np.full(33, 0.9), 0.99, region, mask if segmentation else None)


def test_the_mask_maps_exactly_through_the_roi_warp_into_the_photo_and_the_crop() -> None:
    photo = np.random.default_rng(1).integers(0, 255, (600, 800, 3), dtype=np.uint8)
    loaded = load_image(photo, max_side=500)  # a downscaled working image: 500 × 375
    bbox = (120.0, 60.0, 520.0, 500.0)  # a search region: the runner sees a part of it
    x0, y0, _, _ = search_region(loaded, validated_box(bbox, loaded.original_size))
    assert x0 > 0 and y0 > 0  # the runner's pixels are offset from the working image's
    detector = KeypointDetector(runner=RampRunner(loaded, (x0, y0)))
    mask = detector.detect(loaded, bbox=bbox).person_mask
    assert mask is not None and mask.image_size == (800, 600)

    # Crop pixels -> original photo -> mask pixels: inside the mask grid the value is ramp().
    crop = CropTransform.from_bbox((150.0, 80.0, 450.0, 520.0), size=128)
    in_crop = mask.in_frame(crop.affine_matrix(), (128, 128))
    rows, cols = np.mgrid[0:128, 0:128]
    original = crop.crop_to_image(np.stack([cols, rows], -1).astype(np.float64))
    inverse = cv2.invertAffineTransform(mask.to_photo)
    in_mask = original @ inverse[:, :2].T + inverse[:, 2]
    interior = ((in_mask > 0.5) & (in_mask < MASK_SIZE - 1.5)).all(-1)
    assert interior.mean() > 0.2 and (~interior).mean() > 0.05  # both kinds present
    np.testing.assert_allclose(in_crop[interior], ramp(original[interior]), atol=2e-5)
    outside = ((in_mask < -1) | (in_mask > MASK_SIZE)).any(-1)
    assert outside.any() and (in_crop[outside] == 0).all()  # outside the region: no person

    # The same in photo pixels.
    in_photo = mask.in_photo()
    assert in_photo.shape == (600, 800)
    rows, cols = np.mgrid[0:600, 0:800]
    pixels = np.stack([cols, rows], -1).astype(np.float64)
    in_mask = pixels @ inverse[:, :2].T + inverse[:, 2]
    interior = ((in_mask > 0.5) & (in_mask < MASK_SIZE - 1.5)).all(-1)
    np.testing.assert_allclose(in_photo[interior], ramp(pixels[interior]), atol=2e-5)


class MaskDetector:
    """Fixed keypoints near the photo's left edge and a mask of probability 0.7 everywhere."""

    def __init__(self, keypoints: np.ndarray) -> None:
        self.keypoints = keypoints

    def detect(self, image: LoadedImage, bbox: object = None) -> KeypointDetection:
        width, height = image.original_size
        scale = np.array([[width / 8, 0, width / 16 - 0.5], [0, height / 8, height / 16 - 0.5]])
        mask = PersonMask(np.full((8, 8), 0.7, np.float32), scale, image.original_size)
        return KeypointDetection(
            keypoints=self.keypoints,
            confidences=np.full(17, 0.95),
            person_box=np.array([0.0, 0.0, 1.0, 1.0]),
            mask_box=mask.box(),
            search_box=None,
            image_size=image.original_size,
            seconds=0.0,
            person_mask=mask,
        )


def test_a_box_and_the_photo_edge_clear_the_mask_known_and_leave_the_probability() -> None:
    photo = np.random.default_rng(2).integers(60, 200, (480, 640, 3), dtype=np.uint8)
    keypoints = np.stack([np.linspace(5, 140, 17), np.linspace(60, 420, 17)], 1)
    occluder = (40.5, 250, 200, 330.2)
    prepared = prepare_network_input(
        photo,
        MaskDetector(keypoints),  # type: ignore[arg-type]
        occluders=[occluder],
    )
    mask, known = prepared.person_mask, prepared.person_mask_known
    assert mask is not None and known is not None
    assert mask.shape == known.shape == (256, 256) and mask.dtype == np.float32
    assert known.dtype == bool
    rows, cols = np.mgrid[0:256, 0:256]
    centres = prepared.crop.crop_to_image(np.stack([cols, rows], -1).astype(np.float64))
    in_photo = ((centres > -0.5) & (centres < [639.5, 479.5])).all(-1)
    under = points_under_boxes(centres, [occluder])
    assert (~in_photo).sum() > 1000 and under.sum() > 1000  # both are tested
    np.testing.assert_array_equal(known, in_photo & ~under)
    # The probability is the detector's (it saw the unpainted photo); only `known` changes.
    np.testing.assert_allclose(mask[in_photo & under], 0.7, atol=1e-6)


def test_without_segmentation_there_is_no_mask_and_everything_else_is_unchanged() -> None:
    with KeypointDetector(segmentation=False) as plain, KeypointDetector() as segmenting:
        without = prepare_network_input(SHIPPED_PHOTO, plain)
        with_mask = prepare_network_input(SHIPPED_PHOTO, segmenting)
    assert without.person_mask is None and without.person_mask_known is None
    assert without.detection.person_mask is None and without.detection.mask_box is None
    np.testing.assert_array_equal(without.detection.keypoints, with_mask.detection.keypoints)
    np.testing.assert_array_equal(without.detection.confidences, with_mask.detection.confidences)
    assert torch.equal(without.proxy, with_mask.proxy)
    # BlazePose's own mask on the shipped photo: the person's keypoints lie on it, the crop's
    # corners do not, and the whole crop is inside the photo's known part where it is.
    mask = with_mask.person_mask
    assert mask is not None and with_mask.person_mask_known is not None
    u, v = np.round(with_mask.keypoints_crop).astype(int).T
    on_crop = (u >= 0) & (u < 256) & (v >= 0) & (v < 256)
    assert np.median(mask[v[on_crop], u[on_crop]]) > 0.5
    assert max(mask[0, 0], mask[0, -1], mask[-1, 0], mask[-1, -1]) < 0.5
    assert 0.05 < (mask > 0.5).mean() < 0.6


def test_the_mask_box_is_the_box_of_every_pixel_above_one_half() -> None:
    rng = np.random.default_rng(3)
    probability = cv2.GaussianBlur(rng.uniform(0, 1, (64, 64)).astype(np.float32), (9, 9), 3)
    probability = (probability - probability.min()) / np.ptp(probability)
    to_photo = crop_matrix(Region(np.array([300.0, 200.0]), 250.0, 0.7), 64)
    mask = PersonMask(probability, to_photo, (640, 480))
    rows, cols = np.nonzero(probability > 0.5)
    points = np.stack([cols, rows], 1) @ to_photo[:, :2].T + to_photo[:, 2]
    np.testing.assert_allclose(mask.box(), [*points.min(0), *points.max(0)], atol=1e-9)
    assert PersonMask(np.zeros((8, 8), np.float32), to_photo, (640, 480)).box() is None

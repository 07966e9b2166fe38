"""hkpd's BlazePose pipeline on fixed inputs: anchors, detector decoding, weighted NMS, the
landmark region, the crop warp and its inverse, landmark decoding; and parity with the legacy
mediapipe solution where mediapipe is installed."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from hkpd.prediction.detection.anchors import ssd_anchor_centres
from hkpd.prediction.detection.decoding import (
    Detections,
    box_iou,
    decode_detections,
    decode_landmarks,
    refine_from_heatmap,
    weighted_nms,
)
from hkpd.prediction.detection.warp import Region, crop, letterbox_region, person_region


def test_anchor_layout_matches_the_detector_output() -> None:
    anchors = ssd_anchor_centres()
    assert anchors.shape == (28 * 28 * 2 + 14 * 14 * 2 + 7 * 7 * 6, 2) == (2254, 2)
    # Stride 8: two anchors per cell of a 28x28 map, row by row.
    np.testing.assert_allclose(anchors[0], anchors[1])
    np.testing.assert_allclose(anchors[0], [0.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(anchors[2], [1.5 / 28, 0.5 / 28])
    np.testing.assert_allclose(anchors[2 * 28], [0.5 / 28, 1.5 / 28])
    # Stride 16 starts after 1568 anchors; the three stride-32 layers share a 7x7 map, 6 each.
    np.testing.assert_allclose(anchors[1568], [0.5 / 14, 0.5 / 14])
    np.testing.assert_allclose(anchors[1960:1966], np.tile([0.5 / 7, 0.5 / 7], (6, 1)))
    np.testing.assert_allclose(anchors[-1], [6.5 / 7, 6.5 / 7])


def test_decoding_boxes_keypoints_and_scores() -> None:
    anchors = np.array([[0.25, 0.5], [0.75, 0.5], [0.5, 0.5]])
    raw = np.zeros((3, 12))
    raw[1, :4] = [22.4, -11.2, 44.8, 89.6]  # centre +0.1, -0.05; size 0.2 x 0.4 (of 224)
    raw[1, 4:] = np.arange(8) * 2.24  # keypoint k at +(0.02 k', 0.02 k' + 0.01)
    scores = np.array([-3.0, 2.0, 500.0])  # 0.047, 0.881, clipped to sigmoid(100)
    found = decode_detections(raw, scores[:, None], anchors, min_score=0.5, input_size=224)
    assert len(found) == 2
    np.testing.assert_allclose(found.scores, [1 / (1 + math.exp(-2)), 1.0])
    np.testing.assert_allclose(found.boxes[0], [0.75, 0.25, 0.95, 0.65])
    np.testing.assert_allclose(found.keypoints[0, 0], [0.75, 0.51])
    np.testing.assert_allclose(found.keypoints[0, 3], [0.81, 0.57])
    np.testing.assert_allclose(found.boxes[1], [0.5, 0.5, 0.5, 0.5])


def test_box_iou() -> None:
    box = np.array([0.0, 0.0, 2.0, 2.0])
    others = np.array([[1.0, 0.0, 3.0, 2.0], [0.0, 0.0, 2.0, 2.0], [5.0, 5.0, 6.0, 6.0]])
    np.testing.assert_allclose(box_iou(box, others), [2 / 6, 1.0, 0.0])


def test_weighted_nms_merges_overlapping_detections_by_score() -> None:
    boxes = np.array(
        [[0.1, 0.1, 0.5, 0.5], [0.6, 0.6, 0.9, 0.9], [0.12, 0.1, 0.52, 0.5], [0.0, 0.0, 0.3, 0.3]]
    )
    keypoints = np.arange(4 * 4 * 2, dtype=float).reshape(4, 4, 2)
    scores = np.array([0.6, 0.7, 0.9, 0.55])
    merged = weighted_nms(Detections(boxes, keypoints, scores), iou_threshold=0.3)
    # The 0.9 box absorbs the 0.6 one (IoU 0.9) but not the corner box (IoU 0.17), which stays.
    assert box_iou(boxes[2], boxes[3:])[0] < 0.3
    np.testing.assert_allclose(merged.scores, [0.9, 0.7, 0.55])
    weights = np.array([0.9, 0.6]) / 1.5
    np.testing.assert_allclose(merged.boxes[0], weights @ boxes[[2, 0]])
    np.testing.assert_allclose(
        merged.keypoints[0], np.einsum("n,nkc->kc", weights, keypoints[[2, 0]])
    )
    np.testing.assert_allclose(merged.boxes[1], boxes[1])
    np.testing.assert_allclose(merged.boxes[2], boxes[3])
    empty = weighted_nms(Detections(np.zeros((0, 4)), np.zeros((0, 4, 2)), np.zeros(0)))
    assert len(empty) == 0


@pytest.mark.parametrize(
    ("towards_head", "angle"),
    [
        ((0.0, -1.0), 0.0),
        ((1.0, 0.0), math.pi / 2),
        ((-1.0, 0.0), -math.pi / 2),
        ((0.0, 1.0), -math.pi),
    ],
)
def test_person_region_is_centred_on_the_hips_and_turned_head_up(towards_head, angle) -> None:
    hips = np.array([300.0, 200.0])
    region = person_region(hips, hips + 80 * np.array(towards_head), scale=1.25)
    np.testing.assert_allclose(region.centre, hips)
    assert region.size == pytest.approx(200.0)
    assert -math.pi <= region.angle < math.pi
    assert math.cos(region.angle - angle) == pytest.approx(1.0)
    # The crop's top centre (0.5, 0) lies on the head side of the hips.
    top = region.to_photo(np.array([0.5, 0.0]))
    np.testing.assert_allclose(top, hips + 100 * np.array(towards_head), atol=1e-9)


def test_region_maps_round_trip_and_letterbox() -> None:
    region = Region(np.array([120.0, 80.0]), 64.0, 0.7)
    points = np.random.default_rng(0).uniform(-1, 2, (10, 2))
    np.testing.assert_allclose(region.from_photo(region.to_photo(points)), points, atol=1e-12)
    np.testing.assert_allclose(region.to_photo(np.array([0.5, 0.5])), [120.0, 80.0])
    box = letterbox_region(640, 480)
    np.testing.assert_allclose(
        box.to_photo(np.array([[0.0, 0.0], [1.0, 1.0]])), [[-0.5, -80.5], [639.5, 559.5]]
    )


@pytest.mark.parametrize("angle", [0.0, 0.6, -2.5])
def test_crop_puts_a_photo_point_where_the_region_map_says(angle: float) -> None:
    photo = np.zeros((300, 400, 3), np.uint8)
    photo[148:153, 228:233] = 255  # a 5x5 marker centred on pixel (230, 150)
    region = Region(np.array([210.0, 160.0]), 120.0, angle)
    cut = crop(photo, region, 256, replicate=False)
    rows, cols = np.nonzero(cut[:, :, 0] > 0)
    weights = cut[rows, cols, 0].astype(float)
    centroid = np.array([(cols * weights).sum(), (rows * weights).sum()]) / weights.sum()
    # Crop pixel j samples the photo at to_photo(j / 256) + 0.5 (MediaPipe's half pixel).
    expected = 256 * region.from_photo(np.array([230.0, 150.0]) - 0.5)
    np.testing.assert_allclose(centroid, expected, atol=0.3)
    outside = crop(photo, Region(np.array([-500.0, -500.0]), 50.0, 0.0), 8, replicate=True)
    assert outside.shape == (8, 8, 3) and (outside == 0).all()  # the corner pixel, replicated


def test_landmark_decoding_and_heatmap_refinement() -> None:
    raw = np.zeros((39, 5))
    raw[0] = [128.0, 64.0, 3.0, 0.0, 2.0]
    raw[1] = [10.0, 250.0, 0.0, -2.0, 0.0]
    decoded = decode_landmarks(raw.ravel(), None, 256)
    np.testing.assert_allclose(decoded.points[:2], [[0.5, 0.25], [10 / 256, 250 / 256]])
    np.testing.assert_allclose(decoded.visibility[:2], [0.5, 1 / (1 + math.e**2)])
    np.testing.assert_allclose(decoded.presence[0], 1 / (1 + math.exp(-2)))

    heatmap = np.full((64, 64, 2), -20.0)
    heatmap[17, 30:32, 0] = 20.0  # landmark 0 sits in cell (32, 16); the peak spans cols 30-31
    heatmap[40, 40, 1] = -1.0  # landmark 1: nothing confident near it
    points = np.array([[32.2 / 64, 16.5 / 64], [40.5 / 64, 40.5 / 64]])
    refined = refine_from_heatmap(points, heatmap, kernel=7, min_confidence=0.5)
    np.testing.assert_allclose(refined[0], [30.5 / 64, 17 / 64], atol=1e-6)
    np.testing.assert_allclose(refined[1], points[1])
    far = refine_from_heatmap(np.array([[1.2, 0.5], [0.5, -0.1]]), heatmap)
    np.testing.assert_allclose(far, [[1.2, 0.5], [0.5, -0.1]])


def test_dropping_the_segmentation_head_keeps_the_other_outputs() -> None:
    from hkpd.prediction.detection.models import (
        LANDMARK_MODEL,
        SEGMENTATION_OUTPUT,
        TfliteModel,
        blazepose_model_path,
        drop_output,
    )

    content = blazepose_model_path(LANDMARK_MODEL).read_bytes()
    full, pruned = TfliteModel(content), TfliteModel(drop_output(content, SEGMENTATION_OUTPUT))
    image = np.random.default_rng(1).random((256, 256, 3), dtype=np.float32)
    everything, fewer = full(image), pruned(image)
    assert set(everything) - set(fewer) == {SEGMENTATION_OUTPUT}
    for name, values in fewer.items():
        np.testing.assert_array_equal(values, everything[name])
    with pytest.raises(ValueError, match="no output"):
        drop_output(content, "not_there")


DEMO_PHOTOS = Path("/work/shared/data/demo_photos")
SHIPPED_PHOTO = Path(__file__).parents[1] / "assets" / "photos" / "warrior_lunge.jpg"


@pytest.mark.skipif(
    importlib.util.find_spec("mediapipe") is None, reason="mediapipe (the reference) not installed"
)
def test_parity_with_the_legacy_mediapipe_solution() -> None:
    from hkpd.prediction import COCO_FROM_BLAZEPOSE, KeypointDetector
    from hkpd.prediction.detection.mediapipe_reference import MediapipePose

    photos = [SHIPPED_PHOTO, *sorted(DEMO_PHOTOS.glob("*.jpg"))]
    reference, detector = MediapipePose(), KeypointDetector()
    shifts = []
    for photo in photos:
        theirs, ours = reference.landmarks(photo), detector.landmarks33(photo)
        assert (theirs is None) == (ours is None), photo
        if ours is not None:
            coco = list(COCO_FROM_BLAZEPOSE)
            shifts.append(np.linalg.norm(ours[coco, :2] - theirs[coco, :2], axis=1))
            np.testing.assert_allclose(ours[coco, 2], theirs[coco, 2], atol=0.15)
    reference.close()
    assert np.median(np.concatenate(shifts)) < 2.0
